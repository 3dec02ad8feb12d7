"""How long sim_node's loop waits after a tick: simulated time kept to wall time.

The loop advances the world a tick at a time; ``Pacer.delay`` says how long to sleep
after each so that simulated time runs at ``factor`` times wall time. At factor 0 (as
fast as possible) ticks in which the cell was still (``CellWorld.still``: only the clock
moved) run at real time instead: racing them would turn the seconds the robot waits for
perception or planning into many more simulated seconds than a real cell waits with this
computer, and cost a core for nothing.
"""

from __future__ import annotations

MAX_LAG = 1.0  # s of wall time behind the pace after which it restarts rather than races


class Pacer:
    """Keeps the simulation loop to its real-time factor (0: as fast as possible)."""

    def __init__(self, factor: float) -> None:
        self.factor = factor
        self._pace: float | None = None  # the factor the anchor counts with
        self._anchor = (0.0, 0.0)  # (wall, simulated) s the pace counts from

    def pace(self, still: bool) -> float:
        """Simulated s per wall s for a tick; 0: none (as fast as possible)."""
        if self.factor > 0.0:
            return self.factor
        return 1.0 if still else 0.0

    def delay(self, simulated: float, wall: float, still: bool) -> float:
        """Wall seconds to wait after a tick that ended at ``simulated`` s, at ``wall`` s
        (a monotonic clock); ``still``: the cell was still through it.

        A change of pace (of the factor, or between still and moving ticks at factor 0)
        starts counting from this tick; so does falling more than MAX_LAG behind (e.g.
        after a reset: the loop does not race to catch up)."""
        pace = self.pace(still)
        if pace != self._pace:
            self._pace, self._anchor = pace, (wall, simulated)
            return 0.0
        if pace == 0.0:
            return 0.0
        wall_start, simulated_start = self._anchor
        delay = (simulated - simulated_start) / pace - (wall - wall_start)
        if delay < -MAX_LAG:
            self._anchor = (wall, simulated)
            return 0.0
        return max(delay, 0.0)
