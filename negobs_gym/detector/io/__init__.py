"""Recorded LiDAR files in, :class:`~negobs_gym.core.scan.StructuredScan` out.

- ``.bin``: KITTI-style float32 ``x, y, z, intensity`` (ring from the point order, else from the
  elevation table) or ``x, y, z, intensity, ring`` (numpy only);
- ``.pcd`` with a ``ring``/``channel``/``laser_id`` field (:mod:`~negobs_gym.detector.io.pcd`);
- ROS 1 / ROS 2 bags with ``sensor_msgs/PointCloud2`` (:mod:`~negobs_gym.detector.io.bags`), one
  topic, or a rig's several topics grouped into detector updates (:mod:`~negobs_gym.detector.io.sync`,
  which also deskews a revolution from its points' firing times);
- raw Velodyne ``.pcap`` (:mod:`~negobs_gym.detector.io.pcap`).

The last three need ``pip install negobs_gym[real]`` (pypcd4, rosbags, velodyne-decoder), imported
only when such a file is read; without them a :class:`~negobs_gym.errors.MissingDependencyError`
says what to install. Files that cannot be read raise :class:`~negobs_gym.errors.ScanError`.
All formats are read in the ROS / Velodyne frame (x forward, y left, z up) and converted to this
package's sensor frame; the sensor's mounting comes from :class:`ScanSetup`. A drive's poses, for
multi-frame fusion on a moving vehicle, come from a CSV file (:mod:`~negobs_gym.detector.io.poses`),
a bag's odometry topic or its transform tree (:mod:`~negobs_gym.detector.io.tf`), or a KITTI
odometry sequence or raw drive's OXTS fixes (:mod:`~negobs_gym.detector.io.kitti`).
"""

from negobs_gym.detector.io.poses import POSE_COLUMNS, PoseTrack, pose_from_ros, read_poses_csv
from negobs_gym.detector.io.recording import BinLayout, RecordedFrame, read_bin, read_recording
from negobs_gym.detector.io.setup import RING_FIELD_NAMES, ScanSetup, fields_to_scan

__all__ = [
    "POSE_COLUMNS",
    "RING_FIELD_NAMES",
    "BinLayout",
    "PoseTrack",
    "RecordedFrame",
    "ScanSetup",
    "fields_to_scan",
    "pose_from_ros",
    "read_bin",
    "read_poses_csv",
    "read_recording",
]
