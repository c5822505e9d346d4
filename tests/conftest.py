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


def pytest_collection_modifyitems(config, items):
    """Modules that hold a ``slow`` test first, each module's tests kept together and in order: with ``-n 2`` the
    long end-to-end tests start while the short ones fill the other worker, instead of one long test running alone
    at the end (module-scoped fixtures are set up once per module either way)."""
    heavy = {item.module.__name__ for item in items if item.get_closest_marker("slow") is not None}
    items.sort(key=lambda item: item.module.__name__ not in heavy)  # stable: the collection's order otherwise
