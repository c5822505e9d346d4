"""Real-time pacing of the control loop: one tick per control period, with the achieved timing."""

from __future__ import annotations

import time

from drillgym.errors import InputError

__all__ = ["Pacer"]


class Pacer:
    """Wait for the next tick of a fixed period (s), on ``time.monotonic``.

    ``wait()`` sleeps until the next scheduled tick and returns how late it woke (s).  When the
    caller is more than one period late the schedule restarts from now (no burst of catch-up
    ticks) and ``overruns`` counts it.

    Parameters
    ----------
    period : float
        The period (s), > 0.
    """

    def __init__(self, period: float) -> None:
        if not period > 0:
            raise InputError(f"control period must be > 0 s, got {period!r}")
        self.period = float(period)
        self.next: float | None = None
        self.overruns = 0
        self.last_error = 0.0

    def start(self) -> None:
        """The next tick is now."""
        self.next = time.monotonic()

    def wait(self) -> float:
        """Sleep until the next tick; return how late it woke (s)."""
        if self.next is None:
            self.start()
        now = time.monotonic()
        if now < self.next:
            time.sleep(self.next - now)
            now = time.monotonic()
        self.last_error = now - self.next
        if self.last_error > self.period:
            self.overruns += 1
            self.next = now
        self.next += self.period
        return self.last_error
