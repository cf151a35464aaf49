"""Scan synthesis: a mounted sensor + a ray caster + a vehicle pose -> :class:`StructuredScan`."""

from __future__ import annotations

import numpy as np

from negobs_gym.core.pose import Pose
from negobs_gym.core.scan import StructuredScan, ray_directions
from negobs_gym.sensors.noise import NoiseConfig, apply_noise
from negobs_gym.sensors.raycast.base import RayCaster
from negobs_gym.sensors.rigs import Rig, SensorMount


def scan_rays_world(mount: SensorMount, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """World-frame (N, 3) origins and unit directions of one revolution, laser-major order."""
    m = mount.model
    d_sensor = ray_directions(m.elevation_rad, m.azimuth_rad).reshape(-1, 3)
    r_wv = pose.rotation
    d_world = d_sensor @ (r_wv @ mount.rotation_matrix).T
    origin = pose.to_world(np.asarray(mount.translation_m)[None, :])[0]
    return np.broadcast_to(origin, d_world.shape).copy(), d_world


def scan(
    mount: SensorMount,
    caster: RayCaster,
    pose: Pose,
    *,
    noise: NoiseConfig | None = None,
    rng: np.random.Generator | None = None,
    timestamp_s: float = 0.0,
) -> StructuredScan:
    """One structured scan of ``mount`` at vehicle ``pose``; noise on by default (needs ``rng``)."""
    m = mount.model
    o, d = scan_rays_world(mount, pose)
    ranges = caster.cast(o, d, m.max_range_m).reshape(m.n_lasers, m.n_columns)
    ranges[ranges < m.min_range_m] = np.nan
    ranges = apply_noise(ranges, noise or NoiseConfig(), rng)
    ranges[(ranges < m.min_range_m) | (ranges > m.max_range_m)] = np.nan
    return StructuredScan(
        sensor=mount.name,
        ranges_m=ranges,
        azimuth_rad=m.azimuth_rad,
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
) -> dict[str, StructuredScan]:
    """Scans of every sensor of ``rig``, keyed by mount name."""
    return {
        mt.name: scan(mt, caster, pose, noise=noise, rng=rng, timestamp_s=timestamp_s) for mt in rig.mounts
    }
