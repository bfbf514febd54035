"""The suite's parallel workers keep a module's shared fixture on one worker, set up once.

``make test`` runs ``pytest -n <cores + 1> --dist loadgroup``; tests/conftest.py marks the tests
that use a module-, class- or package-scoped fixture with their file's ``xdist_group``.
pytest-xdist 3.8 carries the group in the test's node id, which pytest 9.2 no longer lets it
change: the groups were then silently ignored and a shared graph was started once per worker (the
demo ran twice per suite). This runs a small suite (tests/workers/shared_fixture_suite.py) on two
real workers through the project's conftest and counts the set-ups.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SUITE = Path(__file__).resolve().parent / "workers" / "shared_fixture_suite.py"


@pytest.mark.slow
def test_a_shared_fixture_is_set_up_once_and_its_tests_stay_on_its_worker(tmp_path: Path
                                                                          ) -> None:
    probe = tmp_path / "probe.txt"
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "2", "--dist", "loadgroup", "-q",
         "-p", "no:cacheprovider", str(SUITE)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={**os.environ, "PUSHBOT_WORKER_PROBE": str(probe)})
    assert result.returncode == 0, result.stdout + result.stderr
    lines = probe.read_text().splitlines()
    setups = [line.split()[1] for line in lines if line.startswith("setup")]
    shared = {line.split()[1] for line in lines if line.startswith("shared")}
    assert len([line for line in lines if line.startswith(("shared", "independent"))]) == 12
    assert len(setups) == 1, lines
    assert shared == set(setups), lines
