"""Shared fixtures."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")

import time

import pytest


def _eventually(condition, timeout: float = 2.0) -> bool:
    """condition() within timeout (s): the emulator executes what the host sent in its own thread, which a
    loaded machine may schedule some milliseconds later."""
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        time.sleep(0.002)
    return condition()


@pytest.fixture
def eventually():
    """``eventually(lambda: ..., timeout=2.0)``: wait for the emulator's state (see :func:`_eventually`)."""
    return _eventually
