"""Scan synthesis: a mounted sensor + a ray caster + a vehicle pose -> :class:`StructuredScan`."""

from __future__ import annotations

import zlib
from functools import lru_cache
from typing import Any

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan, ray_directions
from negobs_gym.errors import ConfigError, InterfaceError
from negobs_gym.sensors.noise import NoiseConfig, add_keyed_noise
from negobs_gym.sensors.raycast.base import RayCaster
from negobs_gym.sensors.rigs import Rig, SensorMount


@lru_cache(maxsize=16)
def directions_vehicle(mount: SensorMount) -> np.ndarray:
    """(N, 3) vehicle-frame unit ray directions of one revolution, laser-major order (read-only)."""
    m = mount.model
    d = ray_directions(m.elevation_rad, m.azimuth_rad).reshape(-1, 3) @ mount.rotation_matrix.T
    d.flags.writeable = False
    return d


@lru_cache(maxsize=16)
def direction_planes(mount: SensorMount) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The x, y and z columns of :func:`directions_vehicle` as contiguous read-only arrays: a
    subset of rays is gathered and rotated plane by plane without strided access."""
    d = directions_vehicle(mount)
    x, y, z = (np.ascontiguousarray(d[:, k]) for k in range(3))
    for plane in (x, y, z):
        plane.flags.writeable = False
    return x, y, z


def rotate_planes(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, rotation: np.ndarray, index: np.ndarray | None = None
) -> np.ndarray:
    """(N, 3) rows ``(x, y, z) @ rotation.T`` from the coordinate planes of N directions (of the
    directions ``index`` of them, when given), computed as :func:`rotate_rows` computes them."""
    planes = [np.asarray(v, dtype=np.float64) for v in (x, y, z)]
    r = np.ascontiguousarray(rotation, dtype=np.float64)
    if index is None:
        return _rotated(*planes, np.empty(0, dtype=np.int64), False, r)
    return _rotated(*planes, np.asarray(index, dtype=np.int64), True, r)


@kernel
def _rotated(
    x: np.ndarray, y: np.ndarray, z: np.ndarray, index: np.ndarray, use_index: bool, r: np.ndarray
) -> np.ndarray:
    """Coordinate i of each output row is ``(x R[i,0] + y R[i,1]) + z R[i,2]`` (compiled: a frame's
    ~260,000 native rays in one pass instead of nine numpy passes)."""
    n = index.size if use_index else x.size
    out = np.empty((n, 3))
    for k in range(n):
        m = index[k] if use_index else k
        xm, ym, zm = x[m], y[m], z[m]
        for i in range(3):
            out[k, i] = xm * r[i, 0] + ym * r[i, 1] + zm * r[i, 2]
    return out


def rotate_rows(directions: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """``directions @ rotation.T`` row by row with elementwise arithmetic, so a row's result does not
    depend on which other rows are in the batch (BLAS kernels may round differently by size).

    Output coordinate i is ``(d0 R[i,0] + d1 R[i,1]) + d2 R[i,2]``.
    """
    d = np.asarray(directions, dtype=np.float64)
    return rotate_planes(d[:, 0], d[:, 1], d[:, 2], rotation)


def scan_rays_world(mount: SensorMount, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """World-frame (N, 3) origins and unit directions of one revolution, laser-major order."""
    d_world = rotate_rows(directions_vehicle(mount), pose.rotation)
    origin = pose.to_world(np.asarray(mount.translation_m)[None, :])[0]
    return np.broadcast_to(origin, d_world.shape).copy(), d_world


def frame_noise_key(rng: np.random.Generator | None, noise: NoiseConfig) -> int:
    """One draw from ``rng`` that keys the noise of every ray of a frame (0 when noise is off)."""
    if not noise.enabled:
        return 0
    if not isinstance(rng, np.random.Generator):
        raise InterfaceError(
            f"rng: noise is enabled: pass an np.random.Generator (or disable noise), got {type(rng).__name__}"
        )
    return int(rng.integers(0, 2**63))


def _sensor_key(frame_key: int, name: str) -> int:
    return (frame_key ^ zlib.crc32(name.encode())) & (2**64 - 1)


def scan(
    mount: SensorMount,
    caster: RayCaster,
    pose: Pose,
    *,
    noise: NoiseConfig | None = None,
    rng: np.random.Generator | None = None,
    timestamp_s: float = 0.0,
    rays: np.ndarray | None = None,
    noise_key: int | None = None,
    columns: tuple[int, int] | None = None,
) -> StructuredScan:
    """One structured scan of ``mount`` at vehicle ``pose``; noise on by default (needs ``rng``).

    ``rays`` (flat laser-major indices) casts only those rays; the others are NaN. Noise is keyed
    per ray (``noise_key``, else one draw from ``rng``), so a ray gets the same range whether the
    full scan or a subset is cast. ``columns`` (``[start, stop)``, holding every ray of ``rays``)
    crops the range image to those columns (:class:`~negobs_gym.sensors.roi.RaySubset`).
    """
    cfg = noise or NoiseConfig()
    key = frame_noise_key(rng, cfg) if noise_key is None else noise_key
    index = _ray_index(mount, rays)
    hit = _cast(mount, caster, pose, index, rays is None) if index.size else np.empty(0)
    return _finish(mount, pose, hit, index, rays is None, cfg, key, columns, timestamp_s)


def _ray_index(mount: SensorMount, rays: np.ndarray | None) -> np.ndarray:
    """The flat indices of the rays of ``mount`` to cast (``rays``: a subset's, checked; None: all)."""
    m = mount.model
    if rays is None:
        return np.arange(m.n_lasers * m.n_columns)
    index = np.asarray(rays)
    if index.ndim != 1 or not np.issubdtype(index.dtype, np.integer):
        raise ConfigError("rays", f"must be a 1-D array of ray indices, got {index.dtype} {index.shape}")
    if index.size and (int(index.min()) < 0 or int(index.max()) >= m.n_lasers * m.n_columns):
        raise ConfigError("rays", f"must index the {m.n_lasers} x {m.n_columns} rays of {mount.name}")
    return index


def _cast(
    mount: SensorMount, caster: RayCaster, pose: Pose, index: np.ndarray, every_ray: bool, start: bool = False
) -> Any:
    """The ranges of rays ``index`` of ``mount`` at vehicle ``pose`` (``every_ray``: all of them,
    in order), or with ``start`` the caster's started cast of them. A caster that rotates a
    sensor's rays itself (``start_rotated_cast``, :class:`EmbreeCaster`) is handed the direction
    table and the pose's rotation; any other gets world rays."""
    origin = pose.to_world(np.asarray(mount.translation_m)[None, :])[0]
    planes = direction_planes(mount)
    subset = None if every_ray else index
    max_range_m = mount.model.max_range_m
    rotated = getattr(caster, "start_rotated_cast", None)
    if rotated is not None:
        pending = rotated(origin, planes, subset, pose.rotation, max_range_m)
        return pending if start else pending.result()
    d = rotate_planes(*planes, pose.rotation, subset)
    o = np.broadcast_to(origin, d.shape)
    return caster.start_cast(o, d, max_range_m) if start else caster.cast(o, d, max_range_m)


def _finish(
    mount: SensorMount,
    pose: Pose,
    hit: np.ndarray,
    index: np.ndarray,
    every_ray: bool,
    cfg: NoiseConfig,
    key: int,
    columns: tuple[int, int] | None,
    timestamp_s: float,
) -> StructuredScan:
    """The scan of ``mount`` from the caster's ranges ``hit`` of rays ``index`` (``every_ray``:
    all of them, in order): sensor range limits, keyed noise, the (cropped) range image."""
    m = mount.model
    hit = np.require(hit, dtype=np.float64, requirements=("C", "W"))  # a caster's own buffer: no copy
    add_keyed_noise(hit, index, cfg, _sensor_key(key, mount.name), m.min_range_m)
    n_columns = m.n_columns
    azimuth = m.azimuth_rad
    start, stop = (0, n_columns) if columns is None else columns
    if every_ray:
        ranges = _in_limits(hit, m.min_range_m, m.max_range_m).reshape(m.n_lasers, n_columns)
    else:  # the (cropped) image filled directly: no full-size image to fill and copy from
        fits = 0 <= start <= stop <= n_columns
        ranges = np.full((m.n_lasers, stop - start if fits else 0), np.nan)
        if not (
            fits and _scatter_in_limits(ranges, hit, index, n_columns, start, m.min_range_m, m.max_range_m)
        ):
            raise ConfigError(
                "columns", f"must be [start, stop) within 0..{n_columns} holding every ray cast"
            )
        azimuth = azimuth[start:stop]
    return StructuredScan(
        sensor=mount.name,
        ranges_m=ranges,
        azimuth_rad=azimuth,
        elevation_rad=m.elevation_rad,
        rotation=mount.rotation_matrix,
        translation_m=np.asarray(mount.translation_m),
        pose=pose,
        timestamp_s=timestamp_s,
    )


@kernel
def _in_limits(hit: np.ndarray, min_range_m: float, max_range_m: float) -> np.ndarray:
    """``hit`` with NaN outside the sensor's range limits [min_range_m, max_range_m] (in place)."""
    for k in range(hit.size):
        if hit[k] < min_range_m or hit[k] > max_range_m:
            hit[k] = np.nan
    return hit


@kernel
def _scatter_in_limits(
    image: np.ndarray,
    hit: np.ndarray,
    index: np.ndarray,
    n_columns: int,
    start: int,
    min_range_m: float,
    max_range_m: float,
) -> bool:
    """In place: ``image[laser, column - start]`` = ray ``index[k]``'s range (laser-major flat
    index into the sensor's rays), NaN outside the range limits (one compiled pass where numpy
    took a divmod, a check and a scatter); False, the image unfinished, where a ray's column lies
    outside the image."""
    width = image.shape[1]
    for k in range(index.size):
        laser, col = index[k] // n_columns, index[k] % n_columns - start
        if col < 0 or col >= width:
            return False
        v = hit[k]
        image[laser, col] = np.nan if (v < min_range_m or v > max_range_m) else v
    return True


def scan_rig(
    rig: Rig,
    caster: RayCaster,
    pose: Pose,
    *,
    noise: NoiseConfig | None = None,
    rng: np.random.Generator | None = None,
    timestamp_s: float = 0.0,
    subsets: dict | None = None,
    crop: bool = False,
) -> dict[str, StructuredScan]:
    """Scans of every sensor of ``rig``, keyed by mount name.

    ``subsets`` (sensor name -> :class:`~negobs_gym.sensors.roi.RaySubset`, from
    :class:`~negobs_gym.sensors.roi.RoiSelector`) casts only those rays of each sensor; the rays
    cast equal the full scan's. One draw from ``rng`` keys the whole frame's noise. ``crop``
    crops each subset's range image to its column span (``RaySubset.columns``): the detectors
    find the same features on fewer columns (docs/performance.md).
    """
    frame = start_rig_scan(
        rig, caster, pose, noise=noise, rng=rng, timestamp_s=timestamp_s, subsets=subsets, crop=crop
    )
    return frame.result()


def start_rig_scan(
    rig: Rig,
    caster: RayCaster,
    pose: Pose,
    *,
    noise: NoiseConfig | None = None,
    rng: np.random.Generator | None = None,
    timestamp_s: float = 0.0,
    subsets: dict | None = None,
    crop: bool = False,
) -> PendingRigScan:
    """:func:`scan_rig`'s frame, started: the sensor with the most rays begins casting on the
    caster's pool threads where it has them (``start_cast``, :class:`EmbreeCaster`), and the
    calling thread asks for the scans it wants first (:meth:`PendingRigScan.scan`) while that
    runs. The scans are the same whatever the order they are asked in. Arguments as
    :func:`scan_rig`'s; the frame's noise key is drawn here."""
    cfg = noise or NoiseConfig()
    return PendingRigScan(rig, caster, pose, cfg, frame_noise_key(rng, cfg), timestamp_s, subsets, crop)


class PendingRigScan:
    """One frame of a rig's scans, each cast when first asked for (:func:`start_rig_scan`).

    ``started`` names the sensor whose cast began at once on the caster's pool threads (None
    where the caster has no ``start_cast``, e.g. the PyBullet backend).
    """

    def __init__(
        self,
        rig: Rig,
        caster: RayCaster,
        pose: Pose,
        noise: NoiseConfig,
        noise_key: int,
        timestamp_s: float,
        subsets: dict | None,
        crop: bool,
    ) -> None:
        self._mounts = {mt.name: mt for mt in rig.mounts}
        self._caster, self._pose, self._noise, self._key = caster, pose, noise, noise_key
        self._timestamp_s = timestamp_s
        subsets = subsets or {}
        self._rays = {name: getattr(subsets.get(name), "index", None) for name in self._mounts}
        self._columns = {
            name: subsets[name].columns if crop and subsets.get(name) is not None else None
            for name in self._mounts
        }
        self._scans: dict[str, StructuredScan] = {}
        self.started: str | None = None
        self._pending: tuple[Any, np.ndarray] | None = None  # the started cast and its ray indices
        if hasattr(caster, "start_cast") and self._mounts:
            name = max(self._mounts, key=self._ray_count)
            rays = self._rays[name]
            index = _ray_index(self._mounts[name], rays)
            if index.size:
                pending = _cast(self._mounts[name], caster, pose, index, rays is None, start=True)
                self._pending = (pending, index)
                self.started = name

    def _ray_count(self, name: str) -> int:
        rays = self._rays[name]
        model = self._mounts[name].model
        return model.n_lasers * model.n_columns if rays is None else len(rays)

    @property
    def names(self) -> tuple[str, ...]:
        """The rig's sensors, in its order."""
        return tuple(self._mounts)

    def scan(self, name: str) -> StructuredScan:
        """The scan of sensor ``name``: cast now on the calling thread, or, for the sensor started
        on the pool threads, the rays they have not taken cast now and theirs waited for.

        Raises:
            ConfigError: ``name`` is not a sensor of the rig.
        """
        done = self._scans.get(name)
        if done is not None:
            return done
        if name not in self._mounts:
            raise ConfigError("name", f"no sensor {name!r} in the rig (sensors: {list(self._mounts)})")
        mount, rays, columns = self._mounts[name], self._rays[name], self._columns[name]
        if name != self.started:
            done = scan(
                mount,
                self._caster,
                self._pose,
                noise=self._noise,
                timestamp_s=self._timestamp_s,
                rays=rays,
                noise_key=self._key,
                columns=columns,
            )
        else:
            pending, index = self._pending
            hit = pending.result()
            done = _finish(
                mount,
                self._pose,
                hit,
                index,
                rays is None,
                self._noise,
                self._key,
                columns,
                self._timestamp_s,
            )
        self._scans[name] = done
        return done

    def result(self) -> dict[str, StructuredScan]:
        """Every sensor's scan, keyed by mount name in the rig's order: the sensors not asked for
        yet cast on this thread first, the one started on the pool threads last."""
        for name in self._mounts:
            if name != self.started:
                self.scan(name)
        return {name: self.scan(name) for name in self._mounts}
