"""The subscription QoS that matches whatever a topic's publishers offer.

A reader must not ask more than a writer offers or DDS never connects them: a reliable
reader gets nothing from a best-effort camera (realsense-ros in sensor-data QoS), a
transient local one nothing from a volatile writer. The recorder and the bring-up's
camera pictures subscribe to topics whose publishers they did not choose, so they ask
the graph what is offered and take the most of it, as rosbag2 does.
"""

from __future__ import annotations

from collections.abc import Iterable

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy


def matching_qos(publishers: Iterable, depth: int) -> QoSProfile:
    """Keep-last ``depth``; transient local if every publisher offers it (a late
    subscriber still gets /tf_static), reliable if every one is (a best-effort reader
    drops a large image whenever one of its fragments is lost). ``publishers``: the
    graph's endpoint infos (``Node.get_publishers_info_by_topic``)."""
    profiles = [publisher.qos_profile for publisher in publishers]
    durable = all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in profiles)
    reliable = all(p.reliability == ReliabilityPolicy.RELIABLE for p in profiles)
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
    )
