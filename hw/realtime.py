"""Keep a control loop on time on a loaded machine: scheduling priority and garbage collection.

The firmware's watchdog (100 ms) stops the motor when the host falls silent; on a busy machine a
host at normal priority, or a full garbage collection of a large heap (torch loaded for a policy),
can stay silent that long although nothing is wrong.  :func:`prioritize` raises the process's
scheduling priority as far as it is allowed (real-time ``SCHED_FIFO`` on request, else a lower nice
value), locks its memory (no page of the loop is reclaimed and read back mid-episode) and says what
it got; :func:`quiet_gc` freezes the objects that exist (they are never
collected again) and suspends the collector during an episode (the loop's garbage is freed by
reference counting).  Neither touches the firmware's safety: the watchdog still stops the motor
100 ms after the last command, whatever the host does.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import os

__all__ = ["prioritize", "quiet_gc", "lock_memory", "freeze_heap"]

NICE = -10  # the nice value asked for (needs CAP_SYS_NICE or root)
RT_PRIORITY = 10  # SCHED_FIFO priority with realtime=True (1..99; low: above every normal process only)
_MCL_CURRENT, _MCL_FUTURE, _MCL_ONFAULT = 1, 2, 4


def lock_memory() -> bool:
    """Keep this process's pages in memory (mlockall, pages locked as they are touched): a page the kernel
    reclaimed while the loop idled costs a disk read when touched again, far longer than a control period."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        return libc.mlockall(_MCL_CURRENT | _MCL_FUTURE | _MCL_ONFAULT) == 0
    except (OSError, AttributeError):
        return False


def prioritize(realtime: bool = False) -> str:
    """Raise this process's scheduling priority as far as allowed; a short description of the result.

    ``realtime``: ask for SCHED_FIFO (the loop sleeps between periods, so it cannot starve the machine
    unless it hangs in a busy loop; the kernel's real-time throttling leaves other processes 5 % even
    then, and the firmware's watchdog stops the motor).  On a loaded 2-core machine nice -10 was not
    enough (reply timeouts and watchdog stops in 4 of 5 runs), SCHED_FIFO was (5 of 5 completed).  Otherwise, or when
    that is refused, ask for nice -10.  Without permission the priority stays as it was (said so)."""
    locked = ", memory locked" if lock_memory() else ""
    return _priority(realtime) + locked


def _priority(realtime: bool) -> str:
    if realtime and hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
            return f"real-time (SCHED_FIFO {RT_PRIORITY})"
        except (PermissionError, OSError):
            pass
    try:
        current = os.getpriority(os.PRIO_PROCESS, 0)
        if current > NICE:
            os.setpriority(os.PRIO_PROCESS, 0, NICE)
        return f"nice {os.getpriority(os.PRIO_PROCESS, 0)}" + (
            " (real-time refused: no permission)" if realtime else ""
        )
    except (PermissionError, OSError, AttributeError):
        return "normal (no permission to raise it: see the README's hardware section)"


@contextlib.contextmanager
def quiet_gc():
    """Within the block: no garbage collection pauses (existing objects frozen, collector off)."""
    was_enabled = gc.isenabled()
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()
        gc.unfreeze()


def freeze_heap() -> int:
    """Collect once, then freeze every object that exists (the collector never scans them again); the number frozen.

    For a process that serves a real-time loop for hours and cannot suspend its collector (the rig emulator): its
    collections then scan only the objects made since, a few hundred, instead of the whole heap of the numerical
    libraries (about 250,000 objects, up to 220 ms for a full collection, measured in the emulator, longer than the
    firmware's watchdog).  Cycles made later are still collected.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()
