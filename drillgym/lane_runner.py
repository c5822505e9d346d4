"""Running the SIMD lane kernel over a batch: whole blocks of lanes, one chunk per core.

The lane kernel (:mod:`drillgym.kernels.lanes`) steps a batch of runs as one vectorised loop.
This module cuts a batch into chunks of whole :data:`LANE_BLOCK`-lane blocks, pads a short chunk
with copies of its last lane, and runs the chunks on the process's threads (the kernel releases
the GIL), so a lane's result does not depend on the batch size, its place in the batch or the
number of cores.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .run_setup import optional_args

__all__ = ["LANE_BLOCK", "LANES_MIN_BATCH", "block_width", "lane_chunks", "pad_lanes", "run_lanes"]

#: batches at least this large use the SIMD lane kernel (fixed-step tableau, exact friction)
LANES_MIN_BATCH = 8
#: lanes per iteration of the lane kernel's widest vectorised loop (LLVM unrolls some loops to four vectors
#: of 8 doubles with AVX-512). Lanes past a loop's last whole iteration would run its remainder loop: 2.5
#: times slower per lane when scalar, and rounded differently, so a lane's last bits would depend on the
#: batch size and the number of cores. :func:`run_lanes` pads every chunk to whole blocks.
LANE_BLOCK = 32


def block_width(n_lanes: int) -> int:
    """Round a number of lanes up to whole blocks of :data:`LANE_BLOCK` lanes.

    Parameters
    ----------
    n_lanes : int
        Number of lanes.

    Returns
    -------
    int
        The padded width.
    """
    return -(-n_lanes // LANE_BLOCK) * LANE_BLOCK


def lane_chunks(n_lanes: int, parallel: bool) -> list[tuple[int, int, int]]:
    """Cut a batch into the chunks of one lane-kernel call.

    Chunks are whole blocks of :data:`LANE_BLOCK` lanes, as even as possible over the cores (one
    chunk unless ``parallel``); the last chunk's width is its lanes rounded up to whole blocks.
    Every lane then runs the vectorised loop body.

    Parameters
    ----------
    n_lanes : int
        Number of lanes (runs) in the batch.
    parallel : bool
        Spread the chunks over the cores.

    Returns
    -------
    list of tuple of (int, int, int)
        ``(first lane, end lane, padded width)`` of each chunk.
    """
    blocks = block_width(n_lanes) // LANE_BLOCK
    n_chunks = min(os.cpu_count() or 1, blocks) if parallel else 1
    per = -(-blocks // n_chunks) * LANE_BLOCK
    return [(lo, min(lo + per, n_lanes), block_width(min(lo + per, n_lanes) - lo)) for lo in range(0, n_lanes, per)]


def pad_lanes(arrays: Sequence[np.ndarray], width: int, out: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Copy arrays into buffers of ``width`` lanes, the last lane repeated into the rest.

    Parameters
    ----------
    arrays : sequence of numpy.ndarray
        Arrays with the lanes along axis 0.
    width : int
        Lanes of the buffers.
    out : list of numpy.ndarray, optional
        Buffers to reuse; all are new when missing or when one has another shape.

    Returns
    -------
    list of numpy.ndarray
        The padded buffers, one per array.
    """
    if out is None or any(b.shape != (width,) + a.shape[1:] for a, b in zip(arrays, out)):
        out = [np.empty((width,) + a.shape[1:], dtype=a.dtype) for a in arrays]
    for a, b in zip(arrays, out):
        n = a.shape[0]
        b[:n] = a
        b[n:] = a[n - 1]
    return out


def run_lanes(
    lanes_run, Y, MODE, U, P, cfg, dt, record_every, OUT, n_steps, parallel, HIST, HEAD, T0, COLS, USTEP, tab
):
    """Run the SIMD lane kernel over a batch, one chunk per core in threads when parallel.

    Chunks are whole blocks of :data:`LANE_BLOCK` lanes (:func:`lane_chunks`): a short chunk is
    padded with copies of its last lane, run, and its real lanes copied back. Used by
    :func:`drillgym.simulate_batch` and the segmented simulation of the identification.

    Parameters
    ----------
    lanes_run : callable
        The composition's compiled ``lanes.lanes_run``.
    Y, MODE : numpy.ndarray
        States ``(B, n_state)`` and friction modes ``(B, 2)``, updated in place.
    U : numpy.ndarray
        Commands (V), as :func:`drillgym.run_setup.input_matrix` gives them.
    P : numpy.ndarray
        Parameter matrix ``(B, n_params)``.
    cfg : int
        Configuration code.
    dt : float
        Integration step (s).
    record_every : int
        Record every k-th step.
    OUT : numpy.ndarray
        Sample-major output ``(n_samples, n_columns, B)``, written in place.
    n_steps : int
        Steps to run.
    parallel : bool
        One chunk per core, in threads.
    HIST, HEAD : numpy.ndarray
        Delay lines and their heads, updated in place.
    T0 : numpy.ndarray
        Start time of each run (s).
    COLS, USTEP : numpy.ndarray or None
        Recorded columns and table steps (see :func:`drillgym.run_setup.optional_args`).
    tab : tuple of numpy.ndarray
        The fixed-step tableau ``(A, b, c)``.
    """
    chunks = lane_chunks(Y.shape[0], parallel)
    FR = np.zeros((Y.shape[0], 2))

    def run(lo, hi, width):
        s = slice(lo, hi)
        if hi - lo == width:
            out = OUT[:, :, s]  # a chunk of the lanes is a strided view: recorded into a C-ordered buffer, so that
            rec = out if out.flags.c_contiguous else np.empty(out.shape)  # one signature is compiled, not two
            lanes_run(
                Y[s],
                MODE[s],
                U[s],
                P[s],
                cfg,
                dt,
                T0[s].copy(),
                record_every,
                rec,
                n_steps,
                True,
                FR[s],
                HIST[s],
                HEAD[s],
                *tab,
                *optional_args(COLS, USTEP, OUT.shape[1]),
            )
            if rec is not out:
                out[...] = rec
            return
        Yp, MODEp, Up, Pp, Tp, FRp, HISTp, HEADp = pad_lanes([a[s] for a in (Y, MODE, U, P, T0, FR, HIST, HEAD)], width)
        OUTp = np.empty(OUT.shape[:2] + (width,))
        lanes_run(
            Yp,
            MODEp,
            Up,
            Pp,
            cfg,
            dt,
            Tp,
            record_every,
            OUTp,
            n_steps,
            True,
            FRp,
            HISTp,
            HEADp,
            *tab,
            *optional_args(COLS, USTEP, OUT.shape[1]),
        )
        n = hi - lo
        Y[s], MODE[s], FR[s], HIST[s], HEAD[s] = Yp[:n], MODEp[:n], FRp[:n], HISTp[:n], HEADp[:n]
        OUT[:, :, s] = OUTp[:, :, :n]

    if len(chunks) == 1:
        run(*chunks[0])
    else:
        list(_chunk_pool().map(lambda c: run(*c), chunks))


_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _chunk_pool() -> ThreadPoolExecutor:
    """The process's threads for the lane kernel's chunks (one per core), started once.

    A pool started per call cost about 1 ms of a 35 ms segmented prediction, with the GIL held.
    Callers on several threads share it (their chunks queue; the cores are the limit either way).
    """
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix="drillgym-lanes")
        return _POOL


def _forget_pool_in_child() -> None:
    """Start the pool and its lock anew in a forked child.

    A child has none of the parent's threads (its pool would never run a chunk) and maybe a lock
    another thread held at the fork.
    """
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool_in_child)
