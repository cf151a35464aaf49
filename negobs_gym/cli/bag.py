"""``negobs bag``: what a recorded ROS bag holds, in the terms of ``negobs detect``'s options.

Lists a bag's PointCloud2 topics (``--topic``, ``--cloud``) with their frame and fields, its pose
topics (``--poses-topic``), its tf tree's edges (``--tf FIXED:BODY``, ``--mount-from-tf``) and
the rest, so that a new recording's command line can be written without ROS tools.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from negobs_gym.detector.io.bags import BagContents, BagTopic


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``bag`` command."""
    parser = subparsers.add_parser(
        "bag",
        help="list a ROS bag's clouds, poses and tf tree for negobs detect",
        description="Lists what ROS 1 / ROS 2 bags hold for `negobs detect`: PointCloud2 topics "
        "(count, approximate rate over the bag, frame_id, points and fields of the first cloud; a "
        "ring field spares the elevation table), pose topics (nav_msgs/Odometry, "
        "geometry_msgs/PoseStamped, PoseWithCovarianceStamped, with their frames), the edges of "
        "the tf tree (/tf timed, /tf_static static) and the other topics. Reads the first message "
        "of each cloud and pose topic and every tf message. Needs `pip install negobs_gym[real]`.",
    )
    parser.add_argument(
        "bags", nargs="+", metavar="BAG", help="a ROS 1 .bag, or a ROS 2 bag's folder, .db3 or .mcap"
    )
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    """Print each bag's contents."""
    from negobs_gym.detector.io.bags import bag_contents

    for path in args.bags:
        print("\n".join(describe(bag_contents(path))))
    return 0


def describe(contents: BagContents) -> list[str]:
    """The lines ``negobs bag`` prints for one bag."""
    from negobs_gym.detector.io.bags import POINTCLOUD2, POSE_MESSAGES, TF_MESSAGES

    lines = [f"{contents.path}: {contents.duration_s:.1f} s, {len(contents.topics)} topics"]
    clouds = contents.of_type(POINTCLOUD2)
    lines.append("  PointCloud2 (--topic TOPIC, --cloud TOPIC:SENSOR):")
    lines += [
        f"    {t.topic}  {t.count} clouds{_rate(t, contents)}  frame {t.frame_id or '-'}  "
        f"{t.points} points{f'  {t.rings} rings' if t.rings else ''}  fields {' '.join(t.fields)}"
        for t in clouds
    ] or ["    none"]
    lines.append("  poses (--poses-topic TOPIC):")
    lines += [
        f"    {t.topic}  {t.msgtype}  {t.count}{_rate(t, contents)}  "
        f"{t.frame_id or '-'} -> {t.child_frame_id or '(its pose)'}"
        for t in contents.of_type(*POSE_MESSAGES)
    ] or ["    none"]
    lines.append("  tf (--tf FIXED:BODY, --mount-from-tf):")
    lines += [
        f"    {e.parent} -> {e.child}  " + ("static" if e.static else f"timed, {e.count} transforms")
        for e in contents.tf_edges
    ] or ["    none"]
    known = (POINTCLOUD2, *POSE_MESSAGES, *TF_MESSAGES)
    other = [t for t in contents.topics if t.msgtype not in known]
    if other:
        lines.append("  other: " + ", ".join(f"{t.topic} ({t.msgtype}, {t.count})" for t in other))
    return lines


def _rate(topic: BagTopic, contents: BagContents) -> str:
    """``~R Hz`` over the bag's span (the topic's own span is not read)."""
    if contents.duration_s <= 0 or topic.count < 2:
        return ""
    return f"  ~{topic.count / contents.duration_s:.1f} Hz"
