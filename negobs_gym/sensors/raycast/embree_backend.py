"""Fast ray-cast backend: Intel Embree through ``embreex`` over a triangle copy of the world.

The static scene holds the terrain — triangulated from the SAME heights PyBullet's heightfield
uses (``World.physics_heightfield``), split along the same diagonal — and every other body that
is not dynamic; a second, small scene holds the dynamic bodies (vehicles) and is rebuilt from
their current PyBullet poses whenever they moved. Excluded bodies (the vehicle carrying the
sensors) are never added. Embree works in float32, so all geometry and ray origins are taken
relative to a local origin at the centre of the terrain (coordinates stay below ~1 km, i.e.
float32 steps below 0.1 mm).
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Iterable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from negobs_gym.errors import ConfigError, MissingDependencyError, ScanError, require
from negobs_gym.sensors.raycast.base import check_rays, raise_ray_problem, rotated_unit_rows
from negobs_gym.sensors.raycast.embree_packets import (
    ISAS,
    PACKET_WIDTHS,
    PacketScene,
    RepairedScene,
    packets_available,
    range_limit,
)
from negobs_gym.sensors.raycast.meshes import Mesh, heightfield_mesh

if TYPE_CHECKING:
    from negobs_gym.sensors.raycast.scene import LinkMesh
    from negobs_gym.sim.world import World

log = logging.getLogger(__name__)


def _embree() -> tuple[Any, Any]:
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as exc:
        raise MissingDependencyError("embreex", "the 'embree' ray-cast backend") from exc
    return rtcore_scene, TriangleMesh


@dataclass(frozen=True, kw_only=True)
class EmbreeConfig:
    """Settings of the Embree backend.

    Attributes:
        max_chord_error_m: Largest gap between a tessellated sphere/cylinder/capsule and the true
            surface [m]; sets the segment count per radius (0.1 mm: 141 segments for a 0.4 m
            wheel). Rays grazing a curved body within ~sqrt(2 r e) of its silhouette can still
            differ from PyBullet's exact shapes by more than 1 cm (about 1e-4 of such hits).
        ground: Which heightfield the terrain mesh is built from: ``"physics"`` = the heights the
            PyBullet body uses (``World.physics_heightfield``, 0.25 m by default; agrees with the
            PyBullet backend), ``"terrain"`` = the terrain's own finer grid (0.1 m by default: pit
            walls stay vertical within 0.1 m instead of sloping over one 0.25 m physics cell; the
            vehicle still drives on the physics heightfield).
        auto_update: Re-read dynamic bodies' poses before every :meth:`EmbreeCaster.cast` (the
            scene is rebuilt only when a pose changed); False = call ``update_dynamic`` yourself.
        threads: Threads one :meth:`EmbreeCaster.cast` shares its rays with (Embree traverses
            without the GIL; every ray's result is the same whatever the split): the calling
            thread and ``threads - 1`` pool threads (:meth:`EmbreeCaster.start_cast`). 1 in
            processes that share the cores with others (vector-env workers).
        ray_packets: Build scenes over shared buffers and cast ray packets through Embree's C
            API (``embree_packets``: same distances bit for bit, scene builds 3-4x and casts
            1.24-1.32x faster); False, or where embreex's library is not found, uses embreex's
            single-ray loop.
        packet_width: Rays per packet (16, 8 or 4; packet path only); None: the widest the
            kernels of ``isa`` cast natively, 16 with AVX-512 and 8 with AVX2 (a 16-ray packet
            on an AVX2-only CPU casts 1.2-1.4x slower). Every width gives the same ranges.
        isa: Embree's kernels (packet path only): ``"native"`` (the CPU's widest, fastest) or one
            instruction set, ``"avx2"`` etc. AVX2 and AVX-512 kernels differ in the last float32
            bit on ~10 % of a frame's rays; a pinned set gives the same ranges on every CPU that
            has it (docs/determinism.md; ``"avx2"`` makes the cast 1.10-1.23x as long on an
            AVX-512 CPU).
        fast_terrain: Cast the static scene with Embree's fast, non-watertight triangle test and
            cast again in a robust scene every ray it may have let through the terrain (misses
            that end under the ground, hits from below, hits on static bodies:
            ``embree_packets.RepairedScene``); ranges then differ from the robust scene's by
            float32 rounding (up to ~1e-4 m), and the cast takes ~0.75x as long on an Intel
            AVX-512 CPU (docs/notebook/performance.md, "The fast terrain test"). False: the robust scene
            alone, whose ranges equal embreex's bit for bit. Packet path only (``ray_packets``);
            a dynamic scene (other vehicles) is always robust.
    """

    max_chord_error_m: float = 1e-4  # docs/sensors.md: agree with PyBullet to 1 cm; 100x margin
    ground: Literal["physics", "terrain"] = "physics"
    auto_update: bool = True
    threads: int = 1
    ray_packets: bool = True
    packet_width: int | None = None
    isa: str = "native"
    fast_terrain: bool = True

    def __post_init__(self) -> None:
        require(
            isinstance(self.max_chord_error_m, (int, float)) and 1e-6 <= self.max_chord_error_m <= 0.1,
            "max_chord_error_m",
            f"must be in [1e-6, 0.1] m, got {self.max_chord_error_m!r}",
        )
        require(
            self.ground in ("physics", "terrain"),
            "ground",
            f"must be 'physics' or 'terrain', got {self.ground!r}",
        )
        require(isinstance(self.auto_update, bool), "auto_update", "must be a bool")
        require(
            isinstance(self.threads, int) and 1 <= self.threads <= 64,
            "threads",
            f"must be an int in [1, 64], got {self.threads!r}",
        )
        require(isinstance(self.ray_packets, bool), "ray_packets", "must be a bool")
        require(isinstance(self.fast_terrain, bool), "fast_terrain", "must be a bool")
        require(
            self.packet_width is None
            or (type(self.packet_width) is int and self.packet_width in PACKET_WIDTHS),
            "packet_width",
            f"must be one of {PACKET_WIDTHS} or None, got {self.packet_width!r}",
        )
        require(self.isa in ISAS, "isa", f"must be one of {ISAS}, got {self.isa!r}")
        require(
            self.isa == "native" or self.ray_packets,
            "isa",
            f"{self.isa!r} needs ray_packets=True (embreex's own loop always runs native kernels)",
        )


_POOLS: dict[int, tuple[int, ThreadPoolExecutor]] = {}
# The smallest chunk a thread takes of a shared cast (~0.5 ms of Embree, far more than taking it);
# a cast of fewer than twice as many rays stays on the calling thread.
_SHARE_MIN_RAYS = 4096


def _thread_pool(n_threads: int) -> ThreadPoolExecutor:
    """One pool per thread count and process (a forked child must not reuse its parent's pool)."""
    pid = os.getpid()
    entry = _POOLS.get(n_threads)
    if entry is None or entry[0] != pid:
        entry = (pid, ThreadPoolExecutor(max_workers=n_threads, thread_name_prefix="embree"))
        _POOLS[n_threads] = entry
    return entry[1]


class _SharedRays:
    """The rays of one static-scene cast, taken in chunks by whichever thread is free: pool
    threads from the front, the thread waiting for the result from the back. The split follows
    each part's real cost (near and far rays differ ~2x), and every ray's distance is the same
    whatever chunk it is cast in."""

    def __init__(self, scene: _Scene, o32: np.ndarray, d32: np.ndarray, max_range_m: float) -> None:
        # o32: one origin per ray (n, 3) or one for all (1, 3)
        self._scene, self.o32, self.d32, self.max_range_m = scene, o32, d32, max_range_m
        n = d32.shape[0]
        self.out = np.empty(n)
        self._lock = threading.Lock()
        self._front, self._back = 0, n  # rays [front, back) are not taken yet
        # pool threads take big chunks (each chunk is a GIL round trip), the waiting thread small
        # ones, so both run out of work at about the same time
        self._front_chunk = max(_SHARE_MIN_RAYS, n // 8)

    def _take(self, size: int, from_front: bool) -> tuple[int, int] | None:
        with self._lock:
            if self._front >= self._back:
                return None
            if from_front:
                lo, hi = self._front, min(self._back, self._front + size)
                self._front = hi
            else:
                lo, hi = max(self._front, self._back - size), self._back
                self._back = lo
        return lo, hi

    def _cast(self, lo: int, hi: int) -> None:
        o = self.o32 if self.o32.shape[0] == 1 else self.o32[lo:hi]
        self._scene.cast(o, self.d32[lo:hi], self.max_range_m, out=self.out[lo:hi])

    def cast_from_front(self) -> None:
        """A pool thread's part: chunks from the front until none is left."""
        while (span := self._take(self._front_chunk, True)) is not None:
            self._cast(*span)

    def cast_from_back(self, chunk: int | None) -> None:
        """The waiting thread's part: chunks of ``chunk`` rays (None: all left) from the back."""
        size = len(self.out) if chunk is None else chunk
        while (span := self._take(size, False)) is not None:
            self._cast(*span)


class PendingCast:
    """A cast started by :meth:`EmbreeCaster.start_cast`; :meth:`result` gives its ranges."""

    def __init__(
        self, rays: _SharedRays, helpers: list[Future], dynamic: _Scene | None, max_range_m: float
    ) -> None:
        self._rays, self._helpers, self._dynamic, self._max_range_m = rays, helpers, dynamic, max_range_m
        self._ranges: np.ndarray | None = None

    def result(self) -> np.ndarray:
        """Ranges [m] of the first hit along each ray (NaN: none within range). The calling thread
        casts the rays no pool thread has taken yet, then waits for the pool threads' chunks; later
        calls return the same array."""
        if self._ranges is None:
            self._rays.cast_from_back(_SHARE_MIN_RAYS if self._helpers else None)
            for helper in self._helpers:
                if not helper.cancel():  # a helper still queued behind other work is not waited for
                    helper.result()  # re-raises a pool thread's error
            rays = self._rays
            ranges = rays.out
            if self._dynamic is not None:  # the nearer hit of the two scenes (fmin: NaN = none)
                np.fmin(ranges, self._dynamic.cast(rays.o32, rays.d32, self._max_range_m), out=ranges)
            self._ranges = ranges
        return self._ranges


class _Scene:
    """One committed Embree scene of one triangle mesh (float32, local coordinates): robust, or,
    with ``fast_heightfield`` > 0 on the packet path, a :class:`RepairedScene` whose first
    ``fast_heightfield`` triangles form the terrain's heightfield."""

    def __init__(
        self,
        mesh: Mesh,
        packets: bool = True,
        isa: str = "native",
        fast_heightfield: int = 0,
        width: int | None = None,
    ) -> None:
        v, f = mesh
        self.n_triangles = int(f.shape[0])
        self._packets: PacketScene | RepairedScene | None = None
        self._embreex: Any = None
        if packets and packets_available():
            if fast_heightfield > 0:
                self._packets = RepairedScene(v, f, fast_heightfield, isa=isa, width=width)
            else:
                self._packets = PacketScene(v, f, robust=True, isa=isa, width=width)
            return
        if isa != "native":
            raise MissingDependencyError(
                "embreex", f"Embree kernels pinned to isa={isa!r} (libembree4 not found)"
            )
        rtcs, triangle_mesh = _embree()
        self._embreex = rtcs.EmbreeScene(robust=True)
        if self.n_triangles:
            triangle_mesh(
                self._embreex, np.ascontiguousarray(v, dtype=np.float32), np.ascontiguousarray(f, np.int32)
            )

    def cast(
        self, o: np.ndarray, d: np.ndarray, max_range_m: float, out: np.ndarray | None = None
    ) -> np.ndarray:
        """float64 ranges (NaN: nothing hit within ``max_range_m``) of float32 rays in local
        coordinates, in ``out`` where given; ``o`` is one origin per ray (n, 3) or one for all (1, 3)."""
        if self._packets is not None:
            return self._packets.cast(o, d, max_range_m, out=out)
        out = np.empty(d.shape[0]) if out is None else out
        if self.n_triangles == 0 or d.shape[0] == 0:
            out[:] = np.nan
            return out
        # a distance query returns tfar alone (no hit records: ~7 % faster); a miss keeps its limit,
        # one float32 step past max_range_m, where a hit would lie beyond max_range_m anyway
        limit = range_limit(max_range_m)
        o = np.ascontiguousarray(np.broadcast_to(o, d.shape))
        t = np.asarray(self._embreex.run(o, d, dists=np.full(d.shape[0], limit), query="DISTANCE"))
        t64 = t.astype(np.float64)
        out[:] = np.where((t < limit) & (t64 <= max_range_m), t64, np.nan)
        return out


class EmbreeCaster:
    """Ray caster over triangle meshes with Embree; implements :class:`~.base.RayCaster`.

    Build it from a world with :meth:`from_world`, or directly from a static mesh in world
    coordinates (``vertices_m`` (V, 3), ``triangles`` (F, 3)); where the mesh's first
    ``heightfield_triangles`` triangles form a heightfield over their whole xy box (a terrain
    grid), ``config.fast_terrain`` casts it with the fast test (0: the robust scene).

    Raises:
        MissingDependencyError: ``embreex`` is not installed.
    """

    def __init__(
        self,
        vertices_m: np.ndarray,
        triangles: np.ndarray,
        *,
        local_origin_m: Iterable[float] | None = None,
        config: EmbreeConfig | None = None,
        heightfield_triangles: int = 0,
    ) -> None:
        _embree()
        self.config = config if config is not None else EmbreeConfig()
        if not isinstance(self.config, EmbreeConfig):
            raise ConfigError("config", f"must be an EmbreeConfig, got {type(self.config).__name__}")
        v = np.asarray(vertices_m, dtype=np.float64)
        f = np.asarray(triangles)
        if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
            raise ConfigError("vertices_m", f"must be finite (V, 3), got shape {v.shape}")
        if f.ndim != 2 or f.shape[1] != 3 or (f.size and (f.min() < 0 or f.max() >= v.shape[0])):
            raise ConfigError("triangles", "must be (F, 3) indices into vertices_m")
        if not (isinstance(heightfield_triangles, int) and 0 <= heightfield_triangles <= f.shape[0]):
            raise ConfigError(
                "heightfield_triangles", f"must be an int in [0, {f.shape[0]}], got {heightfield_triangles!r}"
            )
        if local_origin_m is None:
            local_origin_m = 0.5 * (v.min(axis=0) + v.max(axis=0)) if v.size else np.zeros(3)
        self.local_origin_m = np.asarray(tuple(local_origin_m), dtype=np.float64)
        if self.local_origin_m.shape != (3,) or not np.isfinite(self.local_origin_m).all():
            raise ConfigError("local_origin_m", "must be 3 finite values")
        fast = heightfield_triangles if self.config.fast_terrain else 0
        self._static = self._scene((v - self.local_origin_m, f.astype(np.int32)), fast)
        self._dynamic: _Scene | None = None
        self._world: World | None = None
        self._exclude: frozenset[int] = frozenset()
        self._dyn_links: list[LinkMesh] = []
        self._dyn_ids: tuple[int, ...] = ()
        self._dyn_poses: np.ndarray | None = None

    def _scene(self, mesh: Mesh, fast_heightfield: int = 0) -> _Scene:
        """A scene of ``mesh`` (local coordinates) built the way the config asks."""
        cfg = self.config
        return _Scene(
            mesh,
            packets=cfg.ray_packets,
            isa=cfg.isa,
            fast_heightfield=fast_heightfield,
            width=cfg.packet_width,
        )

    @classmethod
    def from_world(
        cls, world: World, exclude_body_ids: Iterable[int] = (), *, config: EmbreeConfig | None = None
    ) -> EmbreeCaster:
        """Caster over ``world``: terrain, static bodies, and dynamic bodies kept current.

        Bodies created in the world after this call are not seen unless they are registered as
        dynamic (``World.add_dynamic_body``); build a new caster after adding static bodies.

        Raises:
            SimulationError: A body has a collision shape the backend cannot represent.
        """
        import pybullet as p

        from negobs_gym.sensors.raycast.meshes import merge_meshes
        from negobs_gym.sensors.raycast.scene import body_link_meshes, link_poses, world_mesh

        _embree()
        cfg = config if config is not None else EmbreeConfig()
        c = world.client_id
        hf = world.physics_heightfield if cfg.ground == "physics" else world.terrain.heightfield
        x0, x1, y0, y1 = hf.extent_m
        # local origin on a grid sample near the centre, so the local vertex x/y are exact multiples
        res = hf.resolution_m
        ny, nx = hf.heights_m.shape
        origin = np.array([hf.origin_m[0] + (nx // 2) * res, hf.origin_m[1] + (ny // 2) * res, 0.0])
        exclude = frozenset(int(b) for b in exclude_body_ids)
        dynamic = set(world.dynamic_body_ids())
        statics = []
        for k in range(p.getNumBodies(physicsClientId=c)):
            body = p.getBodyUniqueId(k, physicsClientId=c)
            if body == world.terrain_body_id or body in exclude or body in dynamic:
                continue
            links = body_link_meshes(c, body, cfg.max_chord_error_m)
            statics.append(world_mesh(links, link_poses(c, links), origin))
        terrain = heightfield_mesh(hf, origin)
        v, f = merge_meshes([terrain, *statics])  # the terrain's triangles first
        caster = cls(v + origin, f, local_origin_m=origin, config=cfg, heightfield_triangles=len(terrain[1]))
        caster._world = world
        caster._exclude = exclude
        caster.update_dynamic()
        log.debug(
            "embree scene: %d triangles over x [%.1f, %.1f] y [%.1f, %.1f], %d static bodies",
            f.shape[0],
            x0,
            x1,
            y0,
            y1,
            len(statics),
        )
        return caster

    @property
    def n_static_triangles(self) -> int:
        """Triangles in the static scene."""
        return self._static.n_triangles

    @property
    def packet_width(self) -> int | None:
        """Rays per packet of the casts (``config.packet_width`` or the CPU's native width); None
        on embreex's single-ray loop."""
        packets = self._static._packets
        return None if packets is None else packets.width

    def set_dynamic_mesh(self, vertices_m: np.ndarray, triangles: np.ndarray) -> None:
        """Replace the dynamic scene by a mesh in world coordinates (empty arrays clear it)."""
        v = np.asarray(vertices_m, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(triangles).reshape(-1, 3)
        self._dynamic = self._scene((v - self.local_origin_m, f.astype(np.int32))) if f.size else None

    def update_dynamic(self) -> bool:
        """Re-read the world's dynamic bodies and rebuild their scene if any moved; True if rebuilt."""
        if self._world is None:
            return False
        from negobs_gym.sensors.raycast.scene import body_link_meshes, link_poses, world_mesh

        c = self._world.client_id
        ids = tuple(b for b in self._world.dynamic_body_ids() if b not in self._exclude)
        if ids != self._dyn_ids:
            self._dyn_links = [
                lm for b in ids for lm in body_link_meshes(c, b, self.config.max_chord_error_m)
            ]
            self._dyn_ids = ids
            self._dyn_poses = None
        if not self._dyn_links:
            self._dynamic = None
            return False
        poses = link_poses(c, self._dyn_links)
        if self._dyn_poses is not None and np.array_equal(poses, self._dyn_poses):
            return False
        self._dyn_poses = poses
        self._dynamic = self._scene(world_mesh(self._dyn_links, poses, self.local_origin_m))
        return True

    def start_cast(self, origins: np.ndarray, directions: np.ndarray, max_range_m: float) -> PendingCast:
        """Start a cast on the caster's pool threads (``config.threads - 1`` of them) and return
        at once; :meth:`PendingCast.result` casts the rays they have not taken and gives the
        ranges. Meanwhile the calling thread is free for other work (the rig's other sensors,
        docs/performance.md). With one thread, or a few thousand rays, the whole cast runs in
        ``result()``. The world's dynamic bodies are read here, on the calling thread (PyBullet
        is not thread-safe), so pool threads only touch Embree.
        """
        o, d32 = check_rays(origins, directions, max_range_m, dtype=np.float32)
        if o.strides[0] == 0:  # one origin for every ray (a sensor's scan): shifted once, one row
            o32 = (o[:1] - self.local_origin_m).astype(np.float32)
        else:
            o32 = np.ascontiguousarray(o - self.local_origin_m, dtype=np.float32)
        return self._start(o32, d32, float(max_range_m))

    def start_rotated_cast(
        self,
        origin_m: np.ndarray,
        planes: tuple[np.ndarray, np.ndarray, np.ndarray],
        index: np.ndarray | None,
        rotation: np.ndarray,
        max_range_m: float,
    ) -> PendingCast:
        """:meth:`start_cast` of a sensor's rays from one ``origin_m`` (3,): the directions
        with coordinate planes ``planes`` (the rows ``index`` of them; None: all) rotated by
        ``rotation`` as ``sensors.lidar.rotate_planes`` rotates them. Rotated and made unit in
        one pass, with no (n, 3) float64 copy: the ranges are those of ``start_cast`` on the
        rotated rows, bit for bit."""
        o = np.asarray(origin_m, dtype=np.float64).reshape(-1)
        r = np.ascontiguousarray(rotation, dtype=np.float64)
        if o.shape != (3,) or r.shape != (3, 3) or not (np.isfinite(o).all() and np.isfinite(r).all()):
            raise ScanError("origin_m must be 3 finite values and rotation a finite 3 x 3 matrix")
        if not (np.isfinite(max_range_m) and max_range_m > 0):
            raise ScanError(f"max_range_m must be finite and > 0, got {max_range_m}")
        x, y, z = (np.asarray(p, dtype=np.float64) for p in planes)
        idx = np.empty(0, dtype=np.int64) if index is None else np.asarray(index, dtype=np.int64)
        n = x.size if index is None else idx.size
        covered = index is None or n == 0 or 0 <= idx.min() <= idx.max() < x.size
        if not (x.shape == y.shape == z.shape == (x.size,)) or not covered:
            raise ScanError(
                f"planes must be three equal 1-D arrays index covers, got {x.shape}, {y.shape}, {z.shape}"
            )
        d32 = np.empty((n, 3), dtype=np.float32)
        raise_ray_problem(rotated_unit_rows(x, y, z, idx, index is not None, r, d32))
        o32 = (o[None, :] - self.local_origin_m).astype(np.float32)
        return self._start(o32, d32, float(max_range_m))

    def _start(self, o32: np.ndarray, d32: np.ndarray, max_range_m: float) -> PendingCast:
        """Hand local float32 rays (one origin per ray, or one row for all) to the pool threads."""
        if self.config.auto_update:
            self.update_dynamic()
        rays = _SharedRays(self._static, o32, d32, max_range_m)
        helpers: list[Future] = []
        if self.config.threads > 1 and d32.shape[0] >= 2 * _SHARE_MIN_RAYS:
            pool = _thread_pool(self.config.threads - 1)
            helpers = [pool.submit(rays.cast_from_front) for _ in range(self.config.threads - 1)]
        return PendingCast(rays, helpers, self._dynamic, max_range_m)

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range_m: float) -> np.ndarray:
        """Ranges [m] of the first hit along each ray; NaN where nothing is hit within range."""
        return self.start_cast(origins, directions, max_range_m).result()
