"""Error codes of /plan_place (the numbers of dombot_msgs/srv/PlanPlace) and the one
exception the planner raises, so every failure carries a code, a stage and a message."""

from __future__ import annotations

from enum import IntEnum


class ErrorCode(IntEnum):
    SUCCESS = 0
    INVALID_REQUEST = 1
    NO_START_STATE = 2
    OUTSIDE_WORKSPACE = 3
    GRASP_UNREACHABLE = 4
    PLACE_UNREACHABLE = 5
    PLACE_IN_COLLISION = 6
    PLANNING_FAILED = 7
    TIMEOUT = 8


class PlanningError(Exception):
    """A request that cannot be planned; ``stage`` names where it failed."""

    def __init__(self, code: ErrorCode, stage: str, message: str) -> None:
        super().__init__(f"{stage}: {message}")
        self.code = code
        self.stage = stage
        self.message = message
