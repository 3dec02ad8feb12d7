"""Run a plan's segments on a cell as the task does, without its checks between them."""

from __future__ import annotations

from collections.abc import Sequence

from dombot_bringup.task.cell import Segment


def run_segments(cell, segments: Sequence[Segment]) -> None:
    """Each segment's trajectory (asserted to end well), then its gripper command."""
    for segment in segments:
        if len(segment.trajectory.times):
            assert cell.execute(segment.trajectory).ok
        if segment.gripper_after:
            cell.gripper(segment.gripper_position, segment.gripper_max_effort)
