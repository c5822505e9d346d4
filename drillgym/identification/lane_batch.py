"""Lane-kernel runs of jobs on several threads, shared: one kernel call for what the threads ask together.

The lane kernel steps whole blocks of :data:`drillgym.lane_runner.LANE_BLOCK` lanes; a call with fewer lanes
is padded with copies of its last one.  A fit's residual on a 16-segment recording is 16 lanes, so half of
each such call is padding, and so is part of every call whose lanes do not fill whole blocks.  The jobs run
side by side (:func:`run_jobs`: a selection round's fits, the lag/delay searches) ask for such runs at the
same time: here the runs they ask for while every job's thread is waiting go into one kernel call (those of
the same kernel, configuration, step and length), and each thread gets its own lanes back.  A lane's result
does not depend on the batch it runs in (:mod:`drillgym.lane_runner`), so every job's results are those it
would have had alone; only the padding (and the calls' overhead) is saved.

A thread that is not one of a :func:`run_jobs` call's workers runs its lanes at once (:func:`run_shared`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any

import numpy as np

from ..errors import InputError
from ..simulator import run_lanes

__all__ = ["run_jobs", "run_shared", "LaneRequest"]

_LOCAL = threading.local()
#: the errors a kernel run can end with (:meth:`SegmentedModel._simulate` handles them per request)
KERNEL_ERRORS = (SystemError, ZeroDivisionError, FloatingPointError, ValueError)


class LaneRequest:
    """One thread's lane-kernel run, waiting to be run with others.

    Parameters
    ----------
    key : hashable
        What a run it can share a kernel call with has in common (kernel, configuration, step, lengths).
    lanes_run : callable
        The composition's compiled ``lanes.lanes_run``.
    lanes : tuple of numpy.ndarray
        The per-lane arrays ``(Y, MODE, U, P, HIST, HEAD, T0)`` (lanes along axis 0).
    scalars : tuple
        ``(cfg, dt, record_every, n_steps, tab)`` as :func:`drillgym.lane_runner.run_lanes` takes them.
    out_shape : tuple of int
        ``(n_samples, n_columns)`` of the run's recorded output.
    """

    def __init__(
        self, key: Hashable, lanes_run: Callable, lanes: tuple, scalars: tuple, out_shape: tuple[int, int]
    ) -> None:
        self.key, self.lanes_run, self.lanes, self.scalars, self.out_shape = key, lanes_run, lanes, scalars, out_shape
        self.out: np.ndarray | None = None
        self.failed = False
        self.done = False

    @property
    def n(self) -> int:
        """The request's lanes."""
        return self.lanes[0].shape[0]

    def run_alone(self) -> np.ndarray:
        """The run on the request's own arrays (in place), its output ``(n_samples, n_columns, lanes)``."""
        Y, MODE, U, P, HIST, HEAD, T0 = self.lanes
        cfg, dt, rec, n_steps, tab = self.scalars
        OUT = np.empty(self.out_shape + (self.n,))  # the kernel writes every entry
        run_lanes(self.lanes_run, Y, MODE, U, P, cfg, dt, rec, OUT, n_steps, True, HIST, HEAD, T0, None, None, tab)
        return OUT


def _run_group(group: Sequence[LaneRequest]) -> None:
    """Run requests of one key as one kernel call (a copy of their arrays, joined); each gets its lanes'
    output, or is marked failed (it then runs alone, where its own error handling applies)."""
    if len(group) == 1:
        req = group[0]
        try:
            req.out = req.run_alone()
        except KERNEL_ERRORS:
            req.failed = True
        return
    Y, MODE, U, P, T0 = (np.concatenate([r.lanes[i] for r in group]) for i in (0, 1, 2, 3, 6))
    joined = (Y, MODE, U, P, *_delay_lines_of_width(group), T0)
    first = group[0]
    try:
        OUT = LaneRequest(first.key, first.lanes_run, joined, first.scalars, first.out_shape).run_alone()
    except KERNEL_ERRORS:
        for r in group:
            r.failed = True
        return
    lo = 0
    for r in group:
        r.out = OUT[:, :, lo : lo + r.n]
        lo += r.n


def _delay_lines_of_width(group: Sequence[LaneRequest]) -> tuple[np.ndarray, np.ndarray]:
    """The requests' delay lines and heads, joined, each line lengthened to the longest one's width at its old
    end.

    A line holds the commands before its segment's start, newest last (its head); a lane reads at most its
    own line's length minus two steps back (:meth:`drillgym.effects.Composition.delay_line_length` sizes it
    for the longest delay of the request's rows), so the entries added further back are never read, and the
    lane's run is that of its own line."""
    hist, head = [], []
    width = max(r.lanes[4].shape[1] for r in group)
    for r in group:
        H, D = r.lanes[4], r.lanes[5]
        extra = width - H.shape[1]
        if extra and np.any(D < 0):  # an empty line (no Delay effect) has the width of every other one
            raise InputError("delay lines of different widths without a Delay effect")
        hist.append(np.concatenate([np.repeat(H[:, :1], extra, axis=1), H], axis=1) if extra else H)
        head.append(D + extra)
    return np.concatenate(hist), np.concatenate(head)


class _Session:
    """The workers of one :func:`run_jobs` call: how many are running, the runs they are waiting for."""

    def __init__(self, workers: int) -> None:
        self.cond = threading.Condition()
        self.active = workers
        self.pending: list[LaneRequest] = []

    def _take_if_all_wait(self) -> list[LaneRequest]:
        """(Under the lock.) The pending runs when every running worker waits for one, else none."""
        if self.pending and len(self.pending) >= self.active:
            batch, self.pending = self.pending, []
            return batch
        return []

    def _run(self, batch: list[LaneRequest]) -> None:
        """Run a batch (outside the lock), grouped by key in the order asked, and wake its threads."""
        groups: dict[Hashable, list[LaneRequest]] = {}
        for r in batch:
            groups.setdefault(r.key, []).append(r)
        try:
            for group in groups.values():
                _run_group(group)
        finally:
            with self.cond:
                for r in batch:
                    if r.out is None:
                        r.failed = True
                    r.done = True
                self.cond.notify_all()

    def submit(self, req: LaneRequest) -> np.ndarray:
        """Wait until the request has run with the others' (this thread runs the batch when it is the last
        to ask); its output ``(n_samples, n_columns, lanes)``."""
        with self.cond:
            self.pending.append(req)
            batch = self._take_if_all_wait()
            while not batch and not req.done:
                self.cond.wait()
                batch = self._take_if_all_wait() if not req.done else []
        if batch:
            self._run(batch)
        if req.failed:
            return req.run_alone()
        return req.out

    def leave(self) -> None:
        """A worker stops (its jobs are done, or it waits for something else): the others do not wait for it."""
        with self.cond:
            self.active -= 1
            batch = self._take_if_all_wait()
        if batch:
            self._run(batch)

    def rejoin(self) -> None:
        """A worker that left to wait for something else runs again."""
        with self.cond:
            self.active += 1


@contextmanager
def _worker_of(session: _Session | None) -> Iterator[None]:
    """The thread is one of ``session``'s workers within the block (None: none)."""
    previous = getattr(_LOCAL, "session", None)
    _LOCAL.session = session
    try:
        yield
    finally:
        _LOCAL.session = previous


def run_shared(request: LaneRequest) -> np.ndarray:
    """Run a lane-kernel request: with the other workers' of this thread's :func:`run_jobs` call, or at once.

    Parameters
    ----------
    request : LaneRequest
        The run.

    Returns
    -------
    numpy.ndarray
        Its output ``(n_samples, n_columns, lanes)``.

    Raises
    ------
    SystemError, ZeroDivisionError, FloatingPointError, ValueError
        The kernel's error, raised by the request's own run.
    """
    session = getattr(_LOCAL, "session", None)
    if session is None:
        return request.run_alone()
    return session.submit(request)


def run_jobs(jobs: Sequence[Callable[[], Any]], workers: int) -> list[Any]:
    """Each job's result, in the jobs' order, the jobs run on ``workers`` threads whose lane-kernel runs
    (:func:`run_shared`) are shared.

    A worker takes the next job when it has finished one.  A job that runs jobs itself (a nested call) stops
    counting as a worker of this call until they are done, so the others do not wait for it.

    Parameters
    ----------
    jobs : sequence of callables
        Jobs without arguments.
    workers : int
        Threads.

    Returns
    -------
    list
        The jobs' results.

    Raises
    ------
    Exception
        The first error a job raised, in the workers' order.
    """
    jobs = list(jobs)
    workers = max(1, min(workers, len(jobs)))
    results: list[Any] = [None] * len(jobs)
    queue = iter(enumerate(jobs))
    lock = threading.Lock()
    session = _Session(workers)
    outer = getattr(_LOCAL, "session", None)

    def worker() -> None:
        with _worker_of(session):
            try:
                while True:
                    with lock:
                        nxt = next(queue, None)
                    if nxt is None:
                        return
                    results[nxt[0]] = nxt[1]()
            finally:
                session.leave()

    if outer is not None:
        outer.leave()
    try:
        with ThreadPoolExecutor(workers) as pool:
            futures = [pool.submit(worker) for _ in range(workers)]
            for f in futures:
                f.result()
    finally:
        if outer is not None:
            outer.rejoin()
    return results
