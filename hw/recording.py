"""Recording of hardware episodes in the interchange format (docs/data_format.md).

Each episode is one CSV streamed by :class:`drillgym.io.StreamingCsvWriter` (flushed and
fsync'ed in blocks of at most ``flush_interval_s`` of samples, so a killed process loses at
most that much), on a writer thread so that a slow disk never holds up the control loop.  Columns:

processed (SI units, the column names of docs/data_format.md): ``t`` (s, firmware time since the episode start),
``u`` (V, voltage the firmware applied), ``theta_u``, ``theta_l`` (rad, encoders),
``x``, ``y`` (m, LVDTs in the fixed frame, offset at rest removed; lateral configurations),
``x_lp``, ``y_lp`` (m, causal 5 Hz low-pass of x, y, what the policy saw),
``omega_u_est``, ``omega_l_est`` (rad/s, encoder speed estimates);
raw: ``counts_u``, ``counts_l`` (encoder counts), ``lvdt_x_raw``, ``lvdt_y_raw`` (LVDT LSB),
``u_cmd`` (V, the host's command after its safety layer), ``status`` (SAMPLE status bits),
``t_host`` (s, host clock since the episode start).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Mapping
from pathlib import Path

from drillgym.errors import InputError, OutputPathError, SafetyError
from drillgym.io import StreamingCsvWriter, create_directory

__all__ = ["EpisodeRecorder", "RecordingError", "episode_path", "columns"]


class RecordingError(SafetyError):
    """The recording could not be written on (a full disk, an I/O error): the episode is stopped (an episode is
    never run unrecorded) and what was written up to the last flush is kept; the message says where."""


_RAW = ("counts_u", "counts_l", "lvdt_x_raw", "lvdt_y_raw", "u_cmd", "status", "t_host")


def columns(lateral: bool) -> tuple[str, ...]:
    """Column names of a recording; ``lateral`` adds the LVDT columns."""
    lat = ("x", "y", "x_lp", "y_lp") if lateral else ()
    return ("t", "u", "theta_u", "theta_l") + lat + ("omega_u_est", "omega_l_est") + _RAW


def episode_path(record: str | Path, episode: int) -> Path:
    """Where an episode is recorded.

    Parameters
    ----------
    record : str or path
        A ``.csv`` file or a directory.
    episode : int
        Episode number (0-based).

    Returns
    -------
    Path
        ``record`` itself for the first episode and ``<stem>_<k>.csv`` next to it for the others, or
        ``<dir>/<timestamp>_ep<k>.csv`` when ``record`` is a directory.
    """
    p = Path(record)
    if p.suffix.lower() == ".csv":
        return p if episode == 0 else p.with_name(f"{p.stem}_{episode:03d}.csv")
    return p / f"{time.strftime('%Y%m%dT%H%M%S')}_ep{episode:04d}.csv"


class EpisodeRecorder:
    """One episode's recording (see the module docstring for the columns).

    The disk work (formatting, writing, ``fsync`` every ``flush_interval_s`` of samples) happens on a
    writer thread: on a busy machine one ``fsync`` can take longer than the firmware's watchdog, and the
    control loop must not wait for it.  ``write`` only queues the row; ``close`` waits for the thread to
    write and sync the rest.

    Parameters
    ----------
    path : str or path
        The CSV file (its directory is created).
    lateral : bool
        The configuration has LVDT signals (``x``, ``y`` columns).
    meta : mapping
        Metadata written in the file's ``# meta:`` line.
    flush_interval_s : float, optional
        Longest time of samples between two syncs to disk (s, in (0, 1]).  Default 0.5.
    """

    def __init__(self, path: str | Path, lateral: bool, meta: Mapping, flush_interval_s: float = 0.5) -> None:
        if not 0 < flush_interval_s <= 1.0:
            raise InputError(f"flush_interval_s must be in (0, 1] s, got {flush_interval_s!r}")
        self.path = Path(path)
        create_directory(self.path.parent, self.path)
        self.rows = 0
        try:
            self._writer = StreamingCsvWriter(self.path, columns(lateral), meta, flush_interval_s)
        except OSError as exc:
            raise OutputPathError(f"recording {self.path}: cannot be written ({exc.strerror or exc})") from None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._error: BaseException | None = None
        self._reported = False
        self._thread = threading.Thread(target=self._drain, name="recording", daemon=True)
        self._thread.start()
        self.closed = False

    def _drain(self) -> None:
        while True:
            row = self._queue.get()
            if row is None:
                break
            try:
                self._writer.write(row)
            except BaseException as exc:  # noqa: BLE001 - reported by write()/close() on the loop's thread
                self._error = exc
        try:
            self._writer.close()
        except BaseException as exc:  # noqa: BLE001
            self._error = exc

    @property
    def failed(self) -> bool:
        """The writer thread met an error: nothing more is written."""
        return self._error is not None

    def _raise(self) -> None:
        """Report the writer thread's error once, as one line saying what is kept and where."""
        if self._error is None or self._reported:
            return
        self._reported = True
        exc = self._error
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc) or type(exc).__name__
        raise RecordingError(
            f"recording {self.path}: cannot write to it ({why}); the episode is stopped; the recording so far "
            f"(up to its last flush) is kept in {self.path}"
        ) from None

    def write(self, row: Mapping[str, float]) -> None:
        """Queue one sample (column name -> value).

        Raises
        ------
        RecordingError
            The writer thread could not write (said once; later rows are dropped).
        """
        if self._error is not None:
            self._raise()
            return
        self._queue.put(dict(row))
        self.rows += 1

    def close(self) -> None:
        """Flush the rest to disk and close (idempotent).

        Raises
        ------
        RecordingError
            The last rows could not be written (unless already reported by :meth:`write`).
        """
        if not self.closed:
            self.closed = True
            self._queue.put(None)
            self._thread.join()
            self._raise()
