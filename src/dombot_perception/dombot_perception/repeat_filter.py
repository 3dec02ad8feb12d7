"""Lets a repeated log message through once per period, with how often it was held back.

perception_node warns about every camera it leaves out of a request. A client that asks
again and again while a camera is not there yet (a bring-up waiting for the first
frames, a test polling /perception/detect) made it log two lines every few milliseconds:
600 requests filled a 64 KiB stdout pipe nobody read, and the node hung in the write.
The reason stays in each response; the log says it once per period. ROS-free;
thread-safe (the node's detects and placement checks run on threads of their own).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable

MAX_KEPT = 256  # distinct messages remembered; beyond, those older than a period go


class RepeatFilter:
    def __init__(self, period: float, clock: Callable[[], float] = time.monotonic) -> None:
        self.period = period
        self._clock = clock
        self._seen: dict[str, tuple[float, int]] = {}  # message → (last let through, held)
        self._lock = threading.Lock()

    def admit(self, message: str) -> str | None:
        """``message`` if it was not let through within the last period (then with the
        count of repeats held back since), else None."""
        with self._lock:
            return self._admit(message)

    def _admit(self, message: str) -> str | None:
        now = self._clock()
        last, held = self._seen.get(message, (-math.inf, 0))
        if now - last < self.period:
            self._seen[message] = (last, held + 1)
            return None
        self._seen[message] = (now, 0)
        if len(self._seen) > MAX_KEPT:
            self._seen = {m: e for m, e in self._seen.items() if now - e[0] < self.period}
        if held:
            return f"{message} (repeated {held} times since it was logged {now - last:.0f} s ago)"
        return message
