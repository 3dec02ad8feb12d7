"""The QoS the recorder and the bring-up's pictures subscribe with: never more than
every publisher of the topic offers, else DDS would not connect them."""

from __future__ import annotations

from types import SimpleNamespace

from rclpy.qos import (
    DurabilityPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

from dombot_bringup.qos import matching_qos

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(depth=10)


def offering(*profiles: QoSProfile) -> list[SimpleNamespace]:
    """Publishers as Node.get_publishers_info_by_topic describes them."""
    return [SimpleNamespace(qos_profile=profile) for profile in profiles]


def test_latched_reliable_publishers_get_a_latched_reliable_reader() -> None:
    qos = matching_qos(offering(LATCHED, LATCHED), depth=100)
    assert qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert qos.reliability == ReliabilityPolicy.RELIABLE
    assert qos.depth == 100


def test_one_best_effort_camera_makes_the_reader_best_effort() -> None:
    qos = matching_qos(offering(RELIABLE, qos_profile_sensor_data), depth=2)
    assert qos.reliability == ReliabilityPolicy.BEST_EFFORT
    assert qos.durability == DurabilityPolicy.VOLATILE


def test_one_volatile_publisher_makes_the_reader_volatile() -> None:
    qos = matching_qos(offering(LATCHED, RELIABLE), depth=5)
    assert qos.durability == DurabilityPolicy.VOLATILE
    assert qos.reliability == ReliabilityPolicy.RELIABLE
