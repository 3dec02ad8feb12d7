"""The filter that keeps perception_node's log to one line per repeated warning and
period, however often a client asks."""

from __future__ import annotations

from dombot_perception.repeat_filter import MAX_KEPT, RepeatFilter


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_a_repeat_within_the_period_is_held_back_and_counted_when_let_through() -> None:
    clock = Clock()
    repeats = RepeatFilter(10.0, clock)
    assert repeats.admit("camera_0: no frames") == "camera_0: no frames"
    for _ in range(600):
        clock.now += 0.005
        assert repeats.admit("camera_0: no frames") is None
    clock.now = 110.0
    assert repeats.admit("camera_0: no frames") == (
        "camera_0: no frames (repeated 600 times since it was logged 10 s ago)"
    )
    clock.now += 0.1
    assert repeats.admit("camera_0: no frames") is None


def test_different_messages_are_let_through_each() -> None:
    repeats = RepeatFilter(10.0, Clock())
    assert repeats.admit("camera_0: no frames") == "camera_0: no frames"
    assert repeats.admit("camera_1: no frames") == "camera_1: no frames"
    assert repeats.admit("camera_0: no frames") is None


def test_many_distinct_messages_do_not_pile_up() -> None:
    clock = Clock()
    repeats = RepeatFilter(1.0, clock)
    for index in range(10 * MAX_KEPT):
        clock.now += 0.01
        assert repeats.admit(f"frame {index} s old") == f"frame {index} s old"
    assert len(repeats._seen) <= MAX_KEPT + 1
