"""Which cameras sim_node renders at a tick (``cameras.cameras_due``): on demand, at the
camera rate, and at once for a subscriber whose topics matched after a frame went out."""

from __future__ import annotations

from dombot_sim.cameras import cameras_due

PERIOD = 0.5  # s simulated between a watched camera's frames
# subscribers per topic: colour image, depth image, colour info, depth info
NOBODY = (0, 0, 0, 0)
COLOUR_ONLY = (1, 0, 0, 0)
COLOUR_AND_DEPTH = (1, 1, 1, 0)


def test_a_camera_nobody_subscribes_to_is_not_rendered_however_late_its_frame() -> None:
    assert cameras_due(10.0, {"camera_2": 0.0}, {"camera_2": NOBODY}, {}) == []


def test_a_watched_camera_is_rendered_once_a_period() -> None:
    watched = {"camera_2": COLOUR_AND_DEPTH}
    assert cameras_due(1.0, {"camera_2": 1.0}, watched, watched) == ["camera_2"]
    assert cameras_due(1.01, {"camera_2": 1.0 + PERIOD}, watched, watched) == []


def test_a_topic_that_gains_a_subscriber_gets_a_frame_at_once() -> None:
    # the colour topic matched first and got a frame at 1.0; the same reader's depth and
    # info topics matched a tick later: they would have waited for 1.5, and the request
    # with them
    next_frame = {"camera_2": 1.0 + PERIOD}
    due = cameras_due(1.01, next_frame, {"camera_2": COLOUR_AND_DEPTH}, {"camera_2": COLOUR_ONLY})
    assert due == ["camera_2"]


def test_only_the_camera_with_a_new_subscriber_is_rendered_early() -> None:
    next_frame = {"camera_0": 1.5, "camera_2": 1.5}
    audience = {"camera_0": COLOUR_AND_DEPTH, "camera_2": COLOUR_AND_DEPTH}
    last = {"camera_0": COLOUR_AND_DEPTH, "camera_2": COLOUR_ONLY}
    assert cameras_due(1.01, next_frame, audience, last) == ["camera_2"]


def test_a_subscriber_leaving_brings_no_frame_forward() -> None:
    last = {"camera_2": (2, 2, 2, 0)}
    assert cameras_due(1.01, {"camera_2": 1.5}, {"camera_2": COLOUR_AND_DEPTH}, last) == []
