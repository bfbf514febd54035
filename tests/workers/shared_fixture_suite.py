"""A small suite run by tests/test_workers.py under ``pytest -n 2 --dist loadgroup`` (not
collected by the suite itself: the file name does not start with ``test_``).

Its module-scoped fixture records each set-up, and every test the worker it ran on, in the
file named by ``PUSHBOT_WORKER_PROBE``; tests without the fixture give the scheduler something
to spread.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest


def _record(line: str) -> None:
    with Path(os.environ["PUSHBOT_WORKER_PROBE"]).open("a", encoding="utf-8") as out:
        out.write(line + "\n")


@pytest.fixture(scope="module")
def started() -> str:
    """Stands for one started graph shared by the module's tests."""
    _record(f"setup {os.environ.get('PYTEST_XDIST_WORKER', 'main')}")
    return "started"


@pytest.fixture
def client(started: str) -> str:
    """A function-scoped fixture on top of the shared one (as ``demo_out`` on ``demo_run``)."""
    return started


@pytest.mark.parametrize("i", range(3))
def test_uses_the_shared_fixture(started: str, i: int) -> None:
    _record(f"shared {os.environ.get('PYTEST_XDIST_WORKER', 'main')}")


@pytest.mark.parametrize("i", range(3))
def test_uses_it_through_another_fixture(client: str, i: int) -> None:
    _record(f"shared {os.environ.get('PYTEST_XDIST_WORKER', 'main')}")


@pytest.mark.parametrize("i", range(6))
def test_independent(i: int) -> None:
    _record(f"independent {os.environ.get('PYTEST_XDIST_WORKER', 'main')}")
