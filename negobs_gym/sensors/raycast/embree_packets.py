"""Embree scenes and ray packet queries through Embree's C API (the library embreex ships).

embreex binds one query, ``rtcIntersect1`` in a loop over the rays, and copies a mesh into Embree
element by element. The same ``libembree4`` is called here through ctypes: a scene is built over
the mesh's own numpy buffers (``rtcSetSharedGeometryBuffer``: no copy; 3-4x faster builds), and a
compiled loop fills packets of the widest size Embree's kernels run natively (16 rays with
AVX-512, 8 with AVX2: ``rtcIntersect16``, ``rtcIntersect8``; a 16-ray packet on an AVX2-only CPU
is split and casts 1.2-1.4x slower) and casts them, 1.24-1.32x faster than embreex on a LiDAR frame.
Each ray's distance in a robust :class:`PacketScene` equals embreex's bit for bit: the same robust
triangle test on the same float32 inputs, whatever rays share its packet and whatever its width
(tests/sensors/raycast/test_embree_packets.py). :class:`RepairedScene` casts a terrain with
Embree's faster, non-watertight test and casts again, robustly, every ray that test may have let
through. Measured figures: docs/notebook/performance.md, "Embree packets" and "The fast terrain test".

:func:`packets_available` says whether the library was found (embreex's wheels bundle it under
``embreex.libs`` or ``.dylibs``); the backend falls back to embreex's own loop where it is not.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import weakref
from pathlib import Path

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.errors import ConfigError, GeometryError, MissingDependencyError, SimulationError

# Embree 4's C API (include/embree4/rtcore_*.h)
_GEOMETRY_TYPE_TRIANGLE = 0
_BUFFER_TYPE_INDEX = 0
_BUFFER_TYPE_VERTEX = 1
_FORMAT_UINT3 = 0x5003
_FORMAT_FLOAT3 = 0x9003
_SCENE_FLAG_ROBUST = 1 << 2
_PACKET = 16  # the widest packet (rtcIntersect16); the buffers below hold one
PACKET_WIDTHS = (16, 8, 4)  # rtcIntersect16, 8, 4
# RTC_DEVICE_PROPERTY_NATIVE_RAY{16,8,4}_SUPPORTED (include/embree4/rtcore_device.h)
_NATIVE_WIDTH_PROPERTY = {16: 34, 8: 33, 4: 32}
ISAS = ("native", "sse4.2", "avx", "avx2", "avx512")  # Embree device config ``isa=...``
# RTCRayHit16, 64-byte aligned: the ray's 12 fields of 16 lanes (org_x, org_y, org_z, tnear, dir_x,
# dir_y, dir_z, time, tfar, mask, id, flags), then the hit's (Ng_x, Ng_y, Ng_z, u, v, primID, geomID,
# then instID and, in some builds, instPrimID per instance level): 1,344 bytes in embreex's build
# (1 level), 2,240 with 8 levels and instPrimID; the buffer holds either
_PACKET_BYTES = 4096

_NO_FLAGS = np.zeros(0, dtype=np.bool_)  # PacketScene.cast flags no ray
_NO_CEILINGS, _NO_TILES = np.zeros((1, 1)), np.zeros(6)
_u64 = ctypes.c_uint64  # handles and pointers are passed as 64-bit integers (same ABI as a pointer)
_INTERSECT = ctypes.CFUNCTYPE(None, _u64, _u64, _u64, _u64)  # rtcIntersect4/8/16, one signature


def _library_candidates() -> list[Path]:
    import embreex

    pkg = Path(embreex.__file__).parent
    found = []
    for folder in (pkg.parent / "embreex.libs", pkg / ".dylibs", pkg):
        if folder.is_dir():
            found += sorted(p for p in folder.iterdir() if "embree4" in p.name and p.suffix != ".pxd")
    system = ctypes.util.find_library("embree4")
    if system:
        found.append(Path(system))
    return found


class _Library:
    """The loaded ``libembree4`` with the argument types of the functions used here."""

    def __init__(self, path: Path) -> None:
        lib = ctypes.CDLL(str(path))
        sig = {
            "rtcNewDevice": (_u64, [ctypes.c_char_p]),
            "rtcGetDeviceError": (ctypes.c_int, [_u64]),
            "rtcGetDeviceProperty": (ctypes.c_ssize_t, [_u64, ctypes.c_int]),
            "rtcNewScene": (_u64, [_u64]),
            "rtcSetSceneFlags": (None, [_u64, ctypes.c_int]),
            "rtcNewGeometry": (_u64, [_u64, ctypes.c_int]),
            "rtcSetSharedGeometryBuffer": (
                None,
                [
                    _u64,
                    ctypes.c_int,
                    ctypes.c_uint,
                    ctypes.c_int,
                    _u64,
                    ctypes.c_size_t,
                    ctypes.c_size_t,
                    ctypes.c_size_t,
                ],
            ),
            "rtcCommitGeometry": (None, [_u64]),
            "rtcAttachGeometry": (ctypes.c_uint, [_u64, _u64]),
            "rtcReleaseGeometry": (None, [_u64]),
            "rtcCommitScene": (None, [_u64]),
            "rtcReleaseScene": (None, [_u64]),
        }
        for name, (restype, argtypes) in sig.items():
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = restype, argtypes
        self.lib = lib
        self.path = path
        self.intersect = {w: _INTERSECT((f"rtcIntersect{w}", lib)) for w in PACKET_WIDTHS}
        self._devices: dict[str, tuple[int, int]] = {}

    def device(self, isa: str = "native") -> int:
        """One Embree device per process and instruction set (a forked child must not use its
        parent's threads); ``isa="native"`` lets Embree pick the CPU's widest kernels."""
        pid = os.getpid()
        entry = self._devices.get(isa)
        if entry is None or entry[0] != pid:
            handle = self.lib.rtcNewDevice(None if isa == "native" else f"isa={isa}".encode())
            error = self.lib.rtcGetDeviceError(handle) if handle else -1
            if not handle or error:
                raise SimulationError(
                    f"Embree: no device with isa={isa!r} (error {error}); the CPU may lack it, use 'native'"
                )
            entry = (pid, handle)
            self._devices[isa] = entry
        return entry[1]

    def native_width(self, isa: str = "native") -> int:
        """The widest packet the kernels of ``isa`` cast natively (16 where Embree reports none)."""
        device = self.device(isa)
        for width in PACKET_WIDTHS:
            if self.lib.rtcGetDeviceProperty(device, _NATIVE_WIDTH_PROPERTY[width]) > 0:
                return width
        return _PACKET


_LIBRARY: list[_Library | None] = []


def _library() -> _Library | None:
    if not _LIBRARY:
        lib = None
        for path in _library_candidates():
            try:
                lib = _Library(path)
                break
            except (OSError, AttributeError):
                continue
        _LIBRARY.append(lib)
    return _LIBRARY[0]


def packets_available() -> bool:
    """True when embreex's ``libembree4`` can be called directly (packet queries, shared buffers)."""
    try:
        return _library() is not None
    except ImportError:
        return False


def native_packet_width(isa: str = "native") -> int | None:
    """Rays per packet a :class:`PacketScene` casts by default with the kernels of ``isa`` (16 with
    AVX-512, 8 with AVX2 alone); None where the library is not found (:func:`packets_available`)."""
    return _library().native_width(isa) if packets_available() else None


@kernel
def _intersect_packets(
    intersect,
    w: int,
    scene: int,
    o: np.ndarray,
    d: np.ndarray,
    limit: np.float32,
    max_range_m: float,
    out: np.ndarray,
    suspect: np.ndarray,
    n_heightfield: int,
    ceilings: np.ndarray,
    tiles: np.ndarray,
) -> None:
    """``out`` = each float32 ray's range after ``intersect`` (``rtcIntersect<w>``, packets of
    ``w`` <= 16 rays), in float64: its ``tfar`` where
    a hit lies before ``limit`` and within ``max_range_m``, else NaN; ``o`` holds one origin per ray
    or one row for all. Where ``suspect`` holds a flag per ray (it is empty otherwise), it flags
    each ray a non-watertight triangle test may have let through a heightfield made of the first
    ``n_heightfield`` triangles (:class:`RepairedScene`): a hit on a later triangle, a hit on a
    heightfield triangle's underside (its normal, turned to point up, not facing the ray), and a
    miss that ends (at ``max_range_m``, or where it leaves the heightfield's xy box) no higher
    than the heightfield there: ``ceilings`` (ny, nx) bounds it over square tiles, ``tiles`` =
    (x0, y0, tile size, the highest ceiling, x1, y1) with (x0, y0, x1, y1) the box, and a ray
    from outside the box counts when it gets down to the highest ceiling."""
    n = d.shape[0]
    one_origin = o.shape[0] == 1
    flag = suspect.shape[0] == n
    ny, nx = ceilings.shape
    x0, y0, size, highest, x1, y1 = tiles[0], tiles[1], tiles[2], tiles[3], tiles[4], tiles[5]
    work = np.zeros(_PACKET_BYTES + 128, dtype=np.uint8)  # the packet, then the lanes' valid flags
    start = (-work.ctypes.data) % 64
    packet = work[start : start + _PACKET_BYTES]
    f = packet.view(np.float32)
    u = packet.view(np.uint32)
    valid = work[start + _PACKET_BYTES : start + _PACKET_BYTES + 4 * _PACKET].view(np.int32)
    packet_ptr = packet.ctypes.data
    valid_ptr = valid.ctypes.data
    for first in range(0, n, w):
        m = min(w, n - first)
        for k in range(w):
            j = first + k if k < m else first  # idle lanes repeat a real ray and are masked off
            jo = 0 if one_origin else j
            f[k] = o[jo, 0]
            f[w + k] = o[jo, 1]
            f[2 * w + k] = o[jo, 2]
            f[3 * w + k] = 0.0  # tnear
            f[4 * w + k] = d[j, 0]
            f[5 * w + k] = d[j, 1]
            f[6 * w + k] = d[j, 2]
            f[7 * w + k] = 0.0  # time
            f[8 * w + k] = limit  # tfar
            u[9 * w + k] = 0xFFFFFFFF  # mask
            u[10 * w + k] = 0  # id
            u[11 * w + k] = 0  # flags
            u[18 * w + k] = 0xFFFFFFFF  # hit.geomID = RTC_INVALID_GEOMETRY_ID
            valid[k] = -1 if k < m else 0
        intersect(valid_ptr, scene, packet_ptr, 0)
        for k in range(m):
            t = f[8 * w + k]
            out[first + k] = np.float64(t) if t < limit and np.float64(t) <= max_range_m else np.nan
        if flag:
            for k in range(m):
                j = first + k
                if u[18 * w + k] == 0xFFFFFFFF:  # a miss: where it ends, is it under the ground?
                    jo = 0 if one_origin else j
                    ox, oy, oz = np.float64(o[jo, 0]), np.float64(o[jo, 1]), np.float64(o[jo, 2])
                    dx, dy, dz = np.float64(d[j, 0]), np.float64(d[j, 1]), np.float64(d[j, 2])
                    if not (x0 <= ox <= x1 and y0 <= oy <= y1):
                        suspect[j] = oz + min(dz, 0.0) * max_range_m <= highest
                        continue
                    t = max_range_m  # to its range, or out of the heightfield's xy box
                    if dx > 0.0:
                        t = min(t, (x1 - ox) / dx)
                    elif dx < 0.0:
                        t = min(t, (x0 - ox) / dx)
                    if dy > 0.0:
                        t = min(t, (y1 - oy) / dy)
                    elif dy < 0.0:
                        t = min(t, (y0 - oy) / dy)
                    ti = min(max(int((ox + t * dx - x0) / size), 0), nx - 1)
                    tk = min(max(int((oy + t * dy - y0) / size), 0), ny - 1)
                    suspect[j] = oz + t * dz <= ceilings[tk, ti]
                elif u[17 * w + k] >= n_heightfield:  # a body
                    suspect[j] = True
                else:  # Embree's unnormalised normal Ng; a heightfield triangle's upward one is sign(Ng_z) Ng
                    nz = f[14 * w + k]
                    facing = f[12 * w + k] * d[j, 0] + f[13 * w + k] * d[j, 1] + nz * d[j, 2]
                    suspect[j] = facing * nz >= 0.0


@kernel
def _triangle_bounds(v: np.ndarray, f: np.ndarray) -> tuple[float, float, float, float, float]:
    """The largest x or y extent of any triangle of ``f`` over vertices ``v``, and the triangles'
    xy box (x0, y0, x1, y1)."""
    largest = 0.0
    x0, y0, x1, y1 = np.inf, np.inf, -np.inf, -np.inf
    for t in range(f.shape[0]):
        for axis in range(2):
            a, b, c = v[f[t, 0], axis], v[f[t, 1], axis], v[f[t, 2], axis]
            largest = max(largest, max(a, b, c) - min(a, b, c))
        for corner in range(3):
            x, y = v[f[t, corner], 0], v[f[t, corner], 1]
            x0, y0, x1, y1 = min(x0, x), min(y0, y), max(x1, x), max(y1, y)
    return largest, x0, y0, x1, y1


@kernel
def _vertex_tile_maxima(
    v: np.ndarray, f: np.ndarray, x0: float, y0: float, size: float, ny: int, nx: int
) -> np.ndarray:
    """Per square tile, the highest vertex of ``f`` in it (-inf where none)."""
    top = np.full((ny, nx), -np.inf)
    for t in range(f.shape[0]):
        for corner in range(3):
            p = f[t, corner]
            i = min(max(int((v[p, 0] - x0) / size), 0), nx - 1)
            k = min(max(int((v[p, 1] - y0) / size), 0), ny - 1)
            top[k, i] = max(top[k, i], v[p, 2])
    return top


def _heightfield_ceilings(vertices: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Square tiles over a heightfield's xy box and, per tile, a height no point of the surface
    over it exceeds (+1 cm for rounding): the highest vertex in the tile and its 8 neighbours.
    A tile is at least as large as any triangle's x and y extent, so a triangle that reaches into
    a tile has its highest vertex there or in a neighbour. Returns (ceilings, tiles) for
    :func:`_intersect_packets`."""
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(triangles, dtype=np.int64)
    largest, x0, y0, x1, y1 = _triangle_bounds(v, f)  # the box of the heightfield's own vertices
    size = max(2.0, largest * 1.001)
    nx = max(1, int(np.ceil((x1 - x0) / size)))
    ny = max(1, int(np.ceil((y1 - y0) / size)))
    top = np.pad(_vertex_tile_maxima(v, f, x0, y0, size, ny, nx), 1, constant_values=-np.inf)
    ceilings = np.full((ny, nx), -np.inf)
    for a in (0, 1, 2):
        for b in (0, 1, 2):
            np.maximum(ceilings, top[a : a + ny, b : b + nx], out=ceilings)
    ceilings += 0.01
    return ceilings, np.array([x0, y0, size, float(ceilings.max()), x1, y1])


class PacketScene:
    """A committed Embree scene of one triangle mesh over shared buffers, queried in ray packets.

    Args:
        vertices: (V, 3) float32 vertices (local coordinates: Embree works in float32).
        triangles: (F, 3) vertex indices.
        robust: Embree's robust mode (watertight edges: no ray slips between two triangles).
        isa: Embree's kernels: ``"native"`` (the CPU's widest) or one instruction set
            (``"sse4.2"``, ``"avx"``, ``"avx2"``, ``"avx512"``). Kernels of different widths
            round some hits differently in the last float32 bit, so only a pinned set gives the
            same ranges on every CPU that has it (docs/determinism.md).
        width: Rays per packet, 16, 8 or 4; None: the widest the kernels of ``isa`` cast natively
            (:attr:`width`). Every width gives the same ranges.

    Raises:
        MissingDependencyError: embreex's ``libembree4`` was not found (:func:`packets_available`).
        SimulationError: Embree reported an error while building the scene.
        ConfigError: ``width`` is not one of 16, 8, 4, None.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        triangles: np.ndarray,
        robust: bool = True,
        isa: str = "native",
        width: int | None = None,
    ) -> None:
        lib = _library()
        if lib is None:
            raise MissingDependencyError("embreex", "Embree packet queries (libembree4 not found)")
        if width is not None and width not in PACKET_WIDTHS:
            raise ConfigError(
                "width", f"rays per packet must be one of {PACKET_WIDTHS} or None, got {width!r}"
            )
        self._lib = lib
        self.width = lib.native_width(isa) if width is None else int(width)
        v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
        f = np.ascontiguousarray(triangles, dtype=np.uint32).reshape(-1, 3)
        self.n_triangles = int(f.shape[0])
        # Embree reads vertices with 16-byte loads: one padding row past the last vertex
        self._vertices = np.zeros((v.shape[0] + 1, 3), dtype=np.float32)
        self._vertices[:-1] = v
        self._triangles = f
        device = lib.device(isa)
        c = lib.lib
        scene = c.rtcNewScene(device)
        self._scene = scene
        self._finalizer = weakref.finalize(self, _release_scene, c, scene, os.getpid())
        if robust:
            c.rtcSetSceneFlags(scene, _SCENE_FLAG_ROBUST)
        if self.n_triangles:
            geom = c.rtcNewGeometry(device, _GEOMETRY_TYPE_TRIANGLE)
            c.rtcSetSharedGeometryBuffer(
                geom, _BUFFER_TYPE_VERTEX, 0, _FORMAT_FLOAT3, self._vertices.ctypes.data, 0, 12, v.shape[0]
            )
            c.rtcSetSharedGeometryBuffer(
                geom, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, f.ctypes.data, 0, 12, self.n_triangles
            )
            c.rtcCommitGeometry(geom)
            c.rtcAttachGeometry(scene, geom)
            c.rtcReleaseGeometry(geom)
        c.rtcCommitScene(scene)
        error = c.rtcGetDeviceError(device)
        if error:
            raise SimulationError(
                f"Embree: building a scene of {self.n_triangles} triangles failed (code {error})"
            )

    def cast(
        self, o32: np.ndarray, d32: np.ndarray, max_range_m: float, out: np.ndarray | None = None
    ) -> np.ndarray:
        """float64 range of each ray (NaN: nothing hit within ``max_range_m``), in ``out`` where
        given (a float64 array of one value per ray). ``o32``: one origin per ray (n, 3), or one
        row (1, 3) for every ray. A hit counts where its float32 distance lies before the float32
        step past ``max_range_m`` and, in float64, within it."""
        return self._cast(o32, d32, max_range_m, out, _NO_FLAGS, 0, _NO_CEILINGS, _NO_TILES)

    def _cast(
        self,
        o32: np.ndarray,
        d32: np.ndarray,
        max_range_m: float,
        out: np.ndarray | None,
        suspect: np.ndarray,
        n_heightfield: int,
        ceilings: np.ndarray,
        tiles: np.ndarray,
    ) -> np.ndarray:
        """:meth:`cast`, flagging into ``suspect`` (one bool per ray; empty: no flags) the rays
        :class:`RepairedScene` casts again."""
        n = d32.shape[0]
        if o32.shape[0] not in (1, n):
            raise GeometryError(f"origins: one per ray or one for all, got {o32.shape[0]} for {n} rays")
        if out is None:
            out = np.empty(n)
        elif out.shape != (n,) or out.dtype != np.float64:
            raise ConfigError("out", f"needs a float64 array of {n} ranges, got {out.dtype} {out.shape}")
        if n == 0 or self.n_triangles == 0:
            out[:] = np.nan
            suspect[:] = True
            return out
        _intersect_packets(
            self._lib.intersect[self.width],
            self.width,
            self._scene,
            np.ascontiguousarray(o32, dtype=np.float32),
            np.ascontiguousarray(d32, dtype=np.float32),
            range_limit(max_range_m),
            float(max_range_m),
            out,
            suspect,
            int(n_heightfield),
            ceilings,
            tiles,
        )
        return out


class RepairedScene:
    """A mesh led by a heightfield, cast with Embree's fast triangle test; the rays that test may
    have let through the mesh are cast again in a robust scene of the same mesh.

    Embree's default triangle test is not watertight: a ray through a shared edge or vertex can
    slip between the two triangles, and on a LiDAR frame about one ray in 10^5 does (aimed at the
    vertices, a few per cent). Its robust mode closes the gaps and costs 1.1-1.5x the cast
    (docs/performance.md). A heightfield is single-valued in z, so a ray that slipped through it
    stays below its surface until it comes back up through a triangle, which it then meets from
    below, or ends (its range runs out, or it leaves the heightfield's xy box) still below it.
    Cast again in the robust scene: every hit on a heightfield triangle's underside, every hit on
    a later triangle (the bodies standing on the terrain, which a ray could slip into, or meet
    under the ground after slipping through it), and every miss that ends no higher than a
    ceiling of the heightfield kept per 2 m tile. Every other ray keeps the fast test's first hit:
    a ray toward the sky, or one whose range runs out above the ground, cannot have slipped
    through. So no ray passes through the surface; hits and misses are the robust scene's but for
    rays that graze an edge within float32 rounding, and a range differs from the robust scene's
    only by the two tests' rounding (up to ~1e-4 m at 120 m;
    tests/sensors/raycast/test_embree_packets.py). Each ray's range is the same whatever rays are
    cast with it.

    Args:
        vertices: (V, 3) float32 vertices (local coordinates).
        triangles: (F, 3) vertex indices; the first ``n_heightfield`` of them form a heightfield
            that covers its xy box without holes, as a grid's triangulation does (each
            triangle's projection on the xy plane has positive area, and no two overlap).
        n_heightfield: How many leading triangles form the heightfield, >= 1.
        isa, width: Embree's kernels and the rays per packet, as :class:`PacketScene`.
    """

    def __init__(
        self,
        vertices: np.ndarray,
        triangles: np.ndarray,
        n_heightfield: int,
        isa: str = "native",
        width: int | None = None,
    ) -> None:
        v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        if not 1 <= int(n_heightfield) <= f.shape[0]:  # checked before two scenes are built
            raise ConfigError("n_heightfield", f"needs 1 to {f.shape[0]} triangles, got {n_heightfield}")
        self.n_heightfield = int(n_heightfield)
        self.ceilings, self.tiles = _heightfield_ceilings(v, f[: self.n_heightfield])
        self._fast = PacketScene(vertices, triangles, robust=False, isa=isa, width=width)
        self._exact = PacketScene(vertices, triangles, robust=True, isa=isa, width=width)
        self.n_triangles = self._fast.n_triangles
        self.width = self._fast.width

    def cast(
        self, o32: np.ndarray, d32: np.ndarray, max_range_m: float, out: np.ndarray | None = None
    ) -> np.ndarray:
        """float64 range of each ray (NaN: nothing hit within ``max_range_m``), as
        :meth:`PacketScene.cast`."""
        suspect = np.zeros(d32.shape[0], dtype=np.bool_)
        out = self._fast._cast(
            o32, d32, max_range_m, out, suspect, self.n_heightfield, self.ceilings, self.tiles
        )
        again = np.flatnonzero(suspect)
        if again.size:
            o_again = o32 if o32.shape[0] == 1 else o32[again]
            out[again] = self._exact.cast(o_again, d32[again], max_range_m)
        return out


def range_limit(max_range_m: float) -> np.float32:
    """The float32 ``tfar`` a cast starts with: one float32 step past ``max_range_m``, so that a
    hit at the float32 rounding of ``max_range_m`` still counts and a miss keeps this value."""
    return np.nextafter(np.float32(max_range_m), np.float32(np.inf))


def _release_scene(lib: ctypes.CDLL, scene: int, pid: int) -> None:
    if os.getpid() == pid:  # a forked child's copy of the handle belongs to its parent's device
        lib.rtcReleaseScene(scene)
