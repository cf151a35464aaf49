"""How a recorded cloud becomes a structured scan: sensor name, extrinsics, column width, and the
fallback elevation table for clouds that carry no ring (see :mod:`negobs_gym.detector.loaders`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from negobs_gym.core.scan import StructuredScan
from negobs_gym.detector.loaders import (
    HDL64E_AZIMUTH_RESOLUTION_DEG,
    PointOrderConfig,
    RingSource,
    assign_rings,
    azimuth_columns,
    cloud_to_scan,
    column_span,
    measured_ring_elevations,
    ros_to_sensor_frame,
)
from negobs_gym.errors import ScanError, require

#: Names under which recorded files carry the laser index (velodyne driver: ring; Autoware nebula:
#: channel; Ouster / some SDKs: laser_id; SICK's LD-MRS driver (IBEO LUX hardware): layer).
RING_FIELD_NAMES: tuple[str, ...] = ("ring", "channel", "laser_id", "layer")
#: Names under which recorded files carry each point's firing time, as drivers write them:
#: velodyne_pointcloud ``time`` (float s after the header stamp), Ouster ``t`` and Livox
#: ``offset_time`` (integer ns after it), Autoware nebula ``time_stamp`` (integer ns after it),
#: Hesai ``timestamp`` (float s since the epoch). Floats are seconds, integers nanoseconds; a time
#: beyond :data:`ABSOLUTE_TIME_S` is taken as since the epoch and made relative to the stamp.
POINT_TIME_FIELDS: tuple[str, ...] = ("time", "t", "offset_time", "time_stamp", "timestamp")
#: Point times above this [s] are absolute (since the epoch: 11.6 days after 1970), not offsets.
ABSOLUTE_TIME_S = 1e6
#: ROS / Velodyne body axes (x forward, y left, z up) from this package's (X right, Y forward, Z up):
#: ``p_ros = PACKAGE_TO_ROS_BODY @ p`` (the matrix of :func:`ros_to_sensor_frame`'s inverse).
PACKAGE_TO_ROS_BODY = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def mounting_from_ros(position_m: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A sensor's mounting given in ROS body axes (x forward, y left, z up: the sensor frame's
    position and the rotation from it to the body, as a tf edge gives them) as paper N Eq. 9's ``R``
    (3, 3) and ``T`` (3,) in this package's vehicle frame (X right, Y forward, Z up)."""
    to_ros = PACKAGE_TO_ROS_BODY
    position = np.asarray(position_m, dtype=np.float64)
    return to_ros.T @ np.asarray(rotation, dtype=np.float64) @ to_ros, to_ros.T @ position


@dataclass(frozen=True, kw_only=True)
class ScanSetup:
    """The sensor a recording comes from, as the detector needs it.

    Attributes:
        sensor: Scan name, i.e. the detector's key (``"hdl64"`` is the upright spinning path).
        azimuth_resolution_deg: Column width of the range image [deg].
        elevation_rad: Elevation table [rad] for clouds without a ring field when their point order
            is not laser by laser (empty: such clouds are refused).
        rotation: Sensor-to-vehicle rotation ``R`` (paper N Eq. 9).
        translation_m: Sensor origin in the vehicle frame ``T`` [m]; ``T[2]`` is the height.
        columns_centred: Columns centred on multiples of the width, for a fixed-angle scanner
            (:func:`~negobs_gym.detector.loaders.azimuth_columns`).
        crop_columns: The range image spans only the columns from the first to the last with a
            return, for a scanner whose field of view is narrower than a revolution
            (:func:`~negobs_gym.detector.loaders.column_span`); column times crop alike.
        point_order: Thresholds of the ring recovery from the point order, for clouds without a
            ring field (:func:`~negobs_gym.detector.loaders.assign_rings`).
    """

    sensor: str = "hdl64"
    azimuth_resolution_deg: float = HDL64E_AZIMUTH_RESOLUTION_DEG
    elevation_rad: tuple[float, ...] = ()
    rotation: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    translation_m: tuple[float, float, float] = field(default=(0.0, 0.0, 0.0))
    columns_centred: bool = False
    crop_columns: bool = False
    point_order: PointOrderConfig = field(default_factory=PointOrderConfig)

    def __post_init__(self) -> None:
        require(isinstance(self.sensor, str) and bool(self.sensor), "sensor", "must be a non-empty name")
        require(
            math.isfinite(self.azimuth_resolution_deg) and 0 < self.azimuth_resolution_deg <= 360,
            "azimuth_resolution_deg",
            "must be in (0, 360]",
        )
        require(bool(np.isfinite(self.elevation_rad).all()), "elevation_rad", "must be finite")
        require(np.shape(self.rotation) == (3, 3), "rotation", "must be 3x3")
        require(isinstance(self.point_order, PointOrderConfig), "point_order", "must be a PointOrderConfig")
        require(
            len(self.translation_m) == 3 and bool(np.isfinite(self.translation_m).all()),
            "translation_m",
            "must be 3 finite values",
        )

    def scan(
        self,
        xyz_sensor_m: np.ndarray,
        ring: np.ndarray,
        elevation_rad: np.ndarray,
        intensity: np.ndarray | None,
        timestamp_s: float,
    ) -> StructuredScan:
        """Bin a sensor-frame cloud with rings into a scan with this setup's geometry."""
        return cloud_to_scan(
            xyz_sensor_m,
            ring,
            elevation_rad,
            sensor=self.sensor,
            intensity=intensity,
            azimuth_resolution_deg=self.azimuth_resolution_deg,
            rotation=np.asarray(self.rotation),
            translation_m=np.asarray(self.translation_m),
            timestamp_s=timestamp_s,
            columns_centred=self.columns_centred,
            crop_columns=self.crop_columns,
        )


def fields_to_scan(
    fields: dict[str, np.ndarray], setup: ScanSetup, *, source: str, timestamp_s: float = 0.0
) -> tuple[StructuredScan, RingSource]:
    """Scan from named per-point fields in the ROS frame (x forward, y left, z up).

    ``x, y, z`` are required, ``intensity`` optional; the ring comes from the first field of
    :data:`RING_FIELD_NAMES` present (row elevations measured from the points), else from
    :func:`~negobs_gym.detector.loaders.assign_rings` with ``setup.elevation_rad`` and
    ``setup.point_order`` (its fallback to the table warns, naming ``source``). Points with a
    NaN coordinate are dropped (organised clouds mark missing returns so); a cloud with no finite
    point, a missing coordinate or an infinite value raises :class:`ScanError`.
    """
    missing = [k for k in ("x", "y", "z") if k not in fields]
    if missing:
        raise ScanError(f"{source}: no {'/'.join(missing)} field (has {sorted(fields)})")
    xyz = np.column_stack([np.asarray(fields[k], dtype=np.float64).reshape(-1) for k in "xyz"])
    if np.isinf(xyz).any():
        raise ScanError(f"{source}: coordinates contain inf")
    keep = ~np.isnan(xyz).any(axis=1)
    if not keep.any():
        raise ScanError(f"{source}: cloud has no finite point ({xyz.shape[0]} points, all NaN or none)")
    xyz = ros_to_sensor_frame(xyz[keep])
    intensity = fields.get("intensity")
    if intensity is not None:
        intensity = np.asarray(intensity, dtype=np.float64).reshape(-1)[keep]
    ring_name = next((k for k in RING_FIELD_NAMES if k in fields), None)
    if ring_name is not None:
        ring = np.asarray(fields[ring_name]).reshape(-1)[keep]
        if not np.issubdtype(ring.dtype, np.integer):
            ring_f = ring.astype(np.float64)
            if not np.isfinite(ring_f).all() or np.any(ring_f != np.round(ring_f)):
                raise ScanError(f"{source}: {ring_name} field must hold integers")
            ring = ring_f.astype(np.int64)
        compact, elevation = measured_ring_elevations(xyz, ring)
        return setup.scan(xyz, compact, elevation, intensity, timestamp_s), "ring_field"
    if not setup.elevation_rad:
        raise ScanError(
            f"{source}: no ring field ({'/'.join(RING_FIELD_NAMES)}) and no elevation table for this sensor"
        )
    rings = assign_rings(xyz, np.asarray(setup.elevation_rad), source=source, config=setup.point_order)
    return setup.scan(xyz, rings.ring, rings.elevation_rad, intensity, timestamp_s), rings.source


def column_time_offsets(
    fields: dict[str, np.ndarray], setup: ScanSetup, *, source: str, stamp_s: float
) -> np.ndarray:
    """When each column of the cloud's scan was fired, from its points' time field
    (:data:`POINT_TIME_FIELDS`): the mean time of the column's returns after ``stamp_s`` (the
    cloud's header stamp) [s], NaN for a column without returns. All lasers of a spinning sensor
    fire a column within microseconds, so one time per column tells where the vehicle was when
    that part of the revolution was scanned (``detector.io.sync.scan_at_time`` deskews with it).

    Raises:
        ScanError: no time field, or one that is not finite.
    """
    name = next((k for k in POINT_TIME_FIELDS if k in fields), None)
    if name is None:
        raise ScanError(
            f"{source}: no per-point time field ({'/'.join(POINT_TIME_FIELDS)}; has {sorted(fields)})"
        )
    xyz = np.column_stack([np.asarray(fields[k], dtype=np.float64).reshape(-1) for k in "xyz"])
    keep = ~np.isnan(xyz).any(axis=1) & (np.linalg.norm(np.nan_to_num(xyz), axis=1) > 0)
    raw = np.asarray(fields[name]).reshape(-1)[keep]
    times = raw.astype(np.float64) * (1e-9 if np.issubdtype(raw.dtype, np.integer) else 1.0)
    if not np.isfinite(times).all():
        raise ScanError(f"{source}: {name} field holds a value that is not finite")
    if times.size and np.median(times) > ABSOLUTE_TIME_S:
        times = times - stamp_s
    col, n_cols = azimuth_columns(
        ros_to_sensor_frame(xyz[keep]), setup.azimuth_resolution_deg, centred=setup.columns_centred
    )
    if setup.crop_columns:  # the span of cloud_to_scan: the same points give the same columns
        first, stop = column_span(col, n_cols)
        col, n_cols = col - first, stop - first
    count = np.bincount(col, minlength=n_cols)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.bincount(col, weights=times, minlength=n_cols) / np.where(count > 0, count, np.nan)
