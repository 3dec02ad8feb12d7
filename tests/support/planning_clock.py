"""Planning budgets for tests: a verdict comes from the planner's search, never the clock.

The planner's ``Deadline`` is wall-clock (right for a node serving a robot, wrong for a
verdict): a search that proves a domino unreachable by trying every candidate is cut
short on a loaded machine and says TIMEOUT. Tests therefore plan with a budget no search
uses up (``UNHURRIED``), and test TIMEOUT itself on a clock that jumps (``jump_clock``).
"""

from __future__ import annotations

import itertools
import types

import pytest

from dombot_planner import motion

UNHURRIED = 3600.0  # s: longer than any test's search takes on any machine


def jump_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the planner's clock move on a second at every reading: any budget under a
    second is used up at the first check, however fast the machine."""
    seconds = itertools.count()
    monkeypatch.setattr(motion, "time", types.SimpleNamespace(monotonic=lambda: next(seconds)))
