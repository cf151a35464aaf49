"""A recording's transform tree (ROS ``/tf`` and ``/tf_static``) and the vehicle's pose read from it.

ROS drives publish where the vehicle is as a tree of frames (REP-105: ``map`` -> ``odom`` ->
``base_link``, sensors below ``base_link``), each edge on its own clock: wheel odometry at 50 Hz,
a localiser's ``map`` -> ``odom`` correction at 1 Hz, mountings once on ``/tf_static``. The pose of
a body frame in a fixed frame at a frame's time is the chain of edges between them, each edge
interpolated at that time (positions linearly, orientations by slerp, as
:class:`~negobs_gym.detector.io.poses.PoseTrack`) and the edges composed.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from negobs_gym.core.pose import Pose
from negobs_gym.detector.io.poses import PoseTrack, pose_from_ros_transform
from negobs_gym.detector.io.setup import ScanSetup, mounting_from_ros
from negobs_gym.errors import ScanError

__all__ = [
    "TimedTransform",
    "TransformChain",
    "TransformTree",
    "mounting_difference_deg",
    "sensor_mounting",
    "transform_chain",
]


@dataclass(frozen=True)
class TimedTransform:
    """One published edge of the tree: where ``child``'s origin and axes are in ``parent`` (ROS
    axes; a ``geometry_msgs/TransformStamped``) at ``time_s``."""

    time_s: float
    parent: str
    child: str
    position_m: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]


@dataclass(frozen=True, eq=False)
class _Link:
    """One edge on a chain: a timed track or a constant transform, walked forwards or inverted."""

    name: str
    track: PoseTrack | None
    constant: tuple[np.ndarray, Rotation] | None
    inverted: bool

    def transform_at(self, time_s: float) -> tuple[np.ndarray, Rotation]:
        if self.track is None:
            position, rotation = self.constant  # type: ignore[misc]
        else:
            try:
                position, rotation = self.track.transform_at(time_s)
            except ScanError as error:
                raise ScanError(f"tf {self.name}: {error}") from error
        if self.inverted:
            inverse = rotation.inv()
            return -inverse.apply(position), inverse
        return position, rotation


@dataclass(frozen=True, eq=False)
class TransformChain:
    """Where the ``body`` frame is in the ``fixed`` frame at any time: the tree's edges between
    them composed (up from ``fixed`` to their common ancestor inverted, then down to ``body``).
    With ``body_height_m`` > 0 the chain ends that far below ``body`` along its z axis: the
    vehicle's ground point under a ``base_link`` that sits at the axle."""

    fixed: str
    body: str
    links: tuple[_Link, ...]
    body_height_m: float = 0.0

    def transform_at(self, time_s: float) -> tuple[np.ndarray, Rotation]:
        """The ROS body-to-fixed transform (position, rotation) at ``time_s``.

        Raises:
            ScanError: ``time_s`` lies outside a timed edge's span (by more than its gap), named.
        """
        position, rotation = np.zeros(3), Rotation.identity()
        for link in self.links:
            p, r = link.transform_at(time_s)
            position, rotation = position + rotation.apply(p), rotation * r
        if self.body_height_m:
            position = position - rotation.apply([0.0, 0.0, self.body_height_m])
        return position, rotation

    def at(self, time_s: float) -> Pose:
        """This package's :class:`Pose` of the body frame (REP-103 axes, x forward) at ``time_s``."""
        return pose_from_ros_transform(*self.transform_at(time_s))

    @property
    def edges(self) -> tuple[str, ...]:
        """The chain's edges in composition order, ``parent -> child`` (``^-1`` where inverted)."""
        return tuple(link.name + ("^-1" if link.inverted else "") for link in self.links)


def frame_name(name: str) -> str:
    """A frame id as tf2 compares them: without ROS 1 tf's leading slash."""
    return name.lstrip("/")


def transform_chain(
    timed: Iterable[TimedTransform],
    static: Iterable[TimedTransform],
    fixed: str,
    body: str,
    *,
    max_gap_s: float = 0.1,
) -> TransformChain:
    """The chain from ``fixed`` to ``body`` through the tree of ``timed`` and ``static`` edges
    (:meth:`TransformTree.chain`)."""
    return TransformTree(timed, static).chain(fixed, body, max_gap_s=max_gap_s)


class TransformTree:
    """A tree of timed (``/tf``) and static (``/tf_static``, the last one published counts)
    edges, checked once, from which chains between any two of its frames are taken. ``source``
    (e.g. the bag) begins every error message about the tree.

    Raises:
        ScanError: a frame with two parents or an edge both timed and static.
    """

    def __init__(
        self, timed: Iterable[TimedTransform], static: Iterable[TimedTransform], *, source: str = ""
    ) -> None:
        self._prefix = f"{source}: " if source else ""
        self._parent_of: dict[str, str] = {}
        self._samples: dict[str, list[TimedTransform]] = {}
        self._constants: dict[str, TimedTransform] = {}
        for kind, transforms in (("timed", timed), ("static", static)):
            for tf in transforms:
                parent, child = frame_name(tf.parent), frame_name(tf.child)
                if self._parent_of.setdefault(child, parent) != parent:
                    raise ScanError(
                        f"{self._prefix}tf: frame {child!r} has two parents, {self._parent_of[child]!r} and "
                        f"{parent!r} (a tf tree gives each frame one)"
                    )
                if kind == "timed":
                    self._samples.setdefault(child, []).append(tf)
                else:
                    self._constants[child] = tf
        both = sorted(set(self._samples) & set(self._constants))
        if both:
            raise ScanError(f"{self._prefix}tf: frame {both[0]!r} is published both on /tf and /tf_static")
        #: Every frame of the tree, sorted.
        self.frames: list[str] = sorted(set(self._parent_of) | set(self._parent_of.values()))

    def chain(
        self, fixed: str, body: str, *, max_gap_s: float = 0.1, body_height_m: float = 0.0
    ) -> TransformChain:
        """The chain from ``fixed`` to ``body`` (ending ``body_height_m`` below it,
        :class:`TransformChain`). A timed edge's transforms are read in time order; two at the
        same time keep the later published. ``max_gap_s`` is how far outside a timed edge's span a
        frame may lie and take its first or last transform.

        Raises:
            ScanError: a frame that is not in the tree, a loop, or no chain between the two
                frames (two separate trees).
        """
        _check_body_height(body_height_m)
        fixed, body = frame_name(fixed), frame_name(body)
        for name in (fixed, body):
            if name not in self.frames:
                raise ScanError(f"{self._prefix}tf: no frame {name!r} (the tree has {self.frames})")
        from_fixed, from_body = self._up(fixed), self._up(body)
        common = next((f for f in from_body if f in from_fixed), None)
        if common is None:
            raise ScanError(
                f"{self._prefix}tf: no chain from {fixed!r} to {body!r}: they lie in separate trees "
                f"(roots {from_fixed[-1]!r} and {from_body[-1]!r})"
            )
        ups = [self._link(f, True, max_gap_s) for f in from_fixed[: from_fixed.index(common)]]
        downs = [self._link(f, False, max_gap_s) for f in reversed(from_body[: from_body.index(common)])]
        return TransformChain(fixed, body, tuple(ups + downs), body_height_m)

    def _up(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        path = [frame]
        while path[-1] in self._parent_of:
            path.append(self._parent_of[path[-1]])
            if path[-1] in path[:-1]:
                raise ScanError(f"{self._prefix}tf: the frames {path[path.index(path[-1]) :]} form a loop")
        return path

    def _link(self, child: str, inverted: bool, max_gap_s: float) -> _Link:
        """The edge from ``child``'s parent to ``child``."""
        name = f"{self._parent_of[child]} -> {child}"
        if child in self._constants:
            tf = self._constants[child]
            position = np.asarray(tf.position_m, dtype=np.float64)
            quaternion = np.asarray(tf.quaternion_xyzw, dtype=np.float64)
            if not (np.isfinite(position).all() and np.isfinite(quaternion).all()):
                raise ScanError(f"{self._prefix}tf {name}: a position or quaternion is not finite")
            if np.linalg.norm(quaternion) < 1e-9:
                raise ScanError(f"{self._prefix}tf {name}: the quaternion has zero length")
            return _Link(name, None, (position, Rotation.from_quat(quaternion)), inverted)
        ordered = sorted(self._samples[child], key=lambda s: s.time_s)  # stable: the later one last
        times = np.array([s.time_s for s in ordered])
        last = np.append(times[1:] != times[:-1], True)  # of equal times, the later published
        try:
            track = PoseTrack(
                times[last],
                np.array([s.position_m for s in ordered], dtype=np.float64)[last],
                np.array([s.quaternion_xyzw for s in ordered], dtype=np.float64)[last],
                max_gap_s=max_gap_s,
            )
        except ScanError as error:
            raise ScanError(f"{self._prefix}tf {name}: {error}") from error
        return _Link(name, track, None, inverted)


def _check_body_height(body_height_m: float) -> None:
    if not (math.isfinite(body_height_m) and body_height_m >= 0.0):
        raise ScanError(f"body_height_m must be a finite height >= 0 above the ground, got {body_height_m}")


def sensor_mounting(
    tree: TransformTree,
    body: str,
    sensor: str,
    time_s: float,
    *,
    body_height_m: float = 0.0,
    max_gap_s: float = 0.1,
) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's mounting on the vehicle as the tree has it (the chain from ``body`` to the
    cloud's frame ``sensor`` at ``time_s``): paper N Eq. 9's rotation ``R`` (3, 3) and translation
    ``T`` (3,) in this package's vehicle frame (X right, Y forward, Z up), the vehicle's origin
    ``body_height_m`` below ``body``'s (0 for a frame on the ground such as ``base_footprint``), so
    ``T[2]`` is the sensor's height above the ground.

    Raises:
        ScanError: ``sensor`` is not in the tree, or not in ``body``'s, or a timed edge between
            them does not reach ``time_s``.
    """
    _check_body_height(body_height_m)
    position, rotation = tree.chain(body, sensor, max_gap_s=max_gap_s).transform_at(time_s)
    turn, shift = mounting_from_ros(position, rotation.as_matrix())
    return turn, shift + np.array([0.0, 0.0, body_height_m])


def mounting_difference_deg(
    tree: TransformTree, body: str, sensor: str, setup: ScanSetup, time_s: float, *, max_gap_s: float = 0.1
) -> float | None:
    """The angle [deg] between the sensor's orientation on the vehicle by the tree
    (:func:`sensor_mounting`) and by ``setup.rotation`` (what the detector assumes); None when the
    tree cannot say (``sensor`` is not in it, or not in ``body``'s tree, or a timed edge between
    them does not reach ``time_s``). A pitched or rolled sensor the setup takes as upright puts the
    detector's ground where it is not."""
    try:
        on_vehicle, _ = sensor_mounting(tree, body, sensor, time_s, max_gap_s=max_gap_s)
    except ScanError:  # an advisory check: what the tree does not hold is no answer
        return None
    turn = on_vehicle.T @ np.asarray(setup.rotation, dtype=np.float64)
    return float(np.degrees(Rotation.from_matrix(turn).magnitude()))
