"""Scan synthesis: a mounted sensor + a ray caster + a vehicle pose -> :class:`StructuredScan`."""

from __future__ import annotations

import zlib
from functools import lru_cache

import numpy as np

from negobs_gym.core.compiled import kernel
from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan, ray_directions
from negobs_gym.errors import ConfigError
from negobs_gym.sensors.noise import NoiseConfig, apply_keyed_noise
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
        raise TypeError("noise is enabled: pass an np.random.Generator (or disable noise)")
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
    m = mount.model
    cfg = noise or NoiseConfig()
    key = frame_noise_key(rng, cfg) if noise_key is None else noise_key
    if rays is None:
        index = np.arange(m.n_lasers * m.n_columns)
        d = rotate_planes(*direction_planes(mount), pose.rotation)
    else:
        index = np.asarray(rays)
        d = rotate_planes(*direction_planes(mount), pose.rotation, index)
    o = np.broadcast_to(pose.to_world(np.asarray(mount.translation_m)[None, :])[0], d.shape)
    hit = caster.cast(o, d, m.max_range_m) if index.size else np.empty(0)
    hit[hit < m.min_range_m] = np.nan
    hit = apply_keyed_noise(hit, index, cfg, _sensor_key(key, mount.name))
    hit[(hit < m.min_range_m) | (hit > m.max_range_m)] = np.nan
    n_columns = m.n_columns
    azimuth = m.azimuth_rad
    if rays is None:
        ranges = hit.reshape(m.n_lasers, n_columns)
    elif columns is None:
        ranges = np.full(m.n_lasers * n_columns, np.nan)
        ranges[index] = hit
        ranges = ranges.reshape(m.n_lasers, n_columns)
    else:  # the cropped image directly: no full-size image to fill and copy from
        start, stop = columns
        laser, col = np.divmod(index, n_columns)
        if not (0 <= start <= stop <= n_columns and np.all((col >= start) & (col < stop))):
            raise ConfigError(
                "columns", f"must be [start, stop) within 0..{n_columns} holding every ray cast"
            )
        ranges = np.full((m.n_lasers, stop - start), np.nan)
        ranges[laser, col - start] = hit
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
    cfg = noise or NoiseConfig()
    key = frame_noise_key(rng, cfg)
    out = {}
    for mt in rig.mounts:
        sub = subsets.get(mt.name) if subsets is not None else None
        out[mt.name] = scan(
            mt,
            caster,
            pose,
            noise=cfg,
            timestamp_s=timestamp_s,
            rays=None if sub is None else sub.index,
            noise_key=key,
            columns=sub.columns if crop and sub is not None else None,
        )
    return out
