"""BLAS on one thread while drillgym's own threads run the simulations.

The fits' simulations keep every core busy (numba lane kernels, threads of their own); BLAS threads
waiting for work between trf's small dense steps only took cores from them.  And a result must not
depend on how threads happened to interleave: OpenBLAS splits a dot product of more than 10 000 entries
(a residual of 60 s of data) over its threads, so its rounding depends on the thread count at that moment.
``threadpoolctl.threadpool_limits`` is process-wide and restores on exit whatever it found on entry, so
two fits on two threads that enter and leave it interleaved leave BLAS at one or at several threads by
chance (seen: the same diagnose gave two different results on the same recording).  Here the limit is
counted: the first user sets it, the last one gives the caller's setting back.

Known limit: OpenBLAS 0.3.30/0.3.31 (numpy 2.4, scipy 1.17) ignores a thread count set on another thread
once the process's main thread has set one itself (with ``threadpool_limits`` or this block): the fits
then run BLAS at the main thread's setting, the same count every time, so results stay repeatable.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

from threadpoolctl import threadpool_limits

__all__ = ["one_blas_thread", "on_one_blas_thread"]

_LOCK = threading.Lock()
_USERS = 0
_LIMITER: Any = None

F = TypeVar("F", bound=Callable[..., Any])


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Within the block (on any thread), BLAS runs on one thread; when the last block open on any thread
    closes, the setting found by the first one comes back."""
    global _USERS, _LIMITER
    with _LOCK:
        if _USERS == 0:
            _LIMITER = threadpool_limits(limits=1, user_api="blas")
        _USERS += 1
    try:
        yield
    finally:
        with _LOCK:
            _USERS -= 1
            if _USERS == 0:
                _LIMITER.restore_original_limits()
                _LIMITER = None


def on_one_blas_thread(func: F) -> F:
    """A function run inside :func:`one_blas_thread`.

    Parameters
    ----------
    func : callable
        The function.

    Returns
    -------
    callable
        The wrapped function.
    """

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
