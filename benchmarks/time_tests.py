"""The test tiers, timed: wall time and outcome of ``make test-fast`` and ``make test``.

Runs each tier once, as the Makefile does (``python -m pytest -m "not graph and not slow"`` and
``python -m pytest``) in the repository, and writes the ``test_tiers`` section of
``docs/RESULTS.md``: wall time, the pytest summary counts and the 1-minute load average before
and after (the machine may be shared: a loaded machine stretches every figure). Not run by
``run_all.py`` (it would run the whole suite inside ``make bench``).

Usage::

    .venv/bin/python benchmarks/time_tests.py [--tiers fast full] [--no-write]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
#: tier -> (make target, pytest arguments)
TIERS = {"fast": ("make test-fast", ["-m", "not graph and not slow"]),
         "full": ("make test", [])}
_COUNT = re.compile(r"(\d+) (passed|failed|skipped|deselected|errors?|xfailed|xpassed)")


def summary_counts(output: str) -> dict[str, int]:
    """``{outcome: count}`` from pytest's final summary line (``errors`` counted as ``error``).

    >>> summary_counts("== 3 failed, 120 passed, 2 skipped in 61.2s ==")
    {'failed': 3, 'passed': 120, 'skipped': 2}
    """
    lines = [line for line in output.splitlines() if _COUNT.search(line)]
    if not lines:
        return {}
    return {kind.rstrip("s") if kind.startswith("error") else kind: int(n)
            for n, kind in _COUNT.findall(lines[-1])}


def run_tier(name: str) -> dict[str, object]:
    """Run one tier; wall time (s), counts, exit status and load averages."""
    _target, extra = TIERS[name]
    load_before = os.getloadavg()[0]
    start = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                           *extra], cwd=REPO, capture_output=True, text=True, check=False)
    seconds = time.monotonic() - start
    return {"tier": name, "seconds": seconds, "status": proc.returncode,
            "counts": summary_counts(proc.stdout), "load": (load_before, os.getloadavg()[0]),
            "tail": proc.stdout.strip().splitlines()[-1:] or [""]}


def section(results: list[dict[str, object]], command: str) -> str:
    """The ``test_tiers`` section of docs/RESULTS.md."""
    rows = ["| tier | command | wall time | pytest exit | outcome | load avg before / after |",
            "| --- | --- | --- | --- | --- | --- |"]
    for r in results:
        counts = ", ".join(f"{n} {k}" for k, n in r["counts"].items())  # type: ignore[union-attr]
        before, after = r["load"]  # type: ignore[misc]
        rows.append(f"| {r['tier']} | `{TIERS[str(r['tier'])][0]}` | "
                    f"{float(r['seconds']) / 60:.1f} min | {r['status']} | {counts} | "
                    f"{before:.1f} / {after:.1f} |")
    body = ("Each tier run once on this worktree (`-p no:cacheprovider`; the fast tier leaves "
            "out the `graph` and `slow` markers). Wall time from start to exit of pytest; the "
            "load average shows how busy the machine was.\n\n" + "\n".join(rows))
    return format_section("Test tiers (`time_tests`)", command, body)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tiers", nargs="+", choices=sorted(TIERS), default=["fast", "full"])
    parser.add_argument("--no-write", action="store_true", help="print, do not write")
    args = parser.parse_args(argv)
    results = []
    for name in args.tiers:
        print(f"== {name}", flush=True)
        results.append(run_tier(name))
        print(results[-1], flush=True)
    text = section(results, "python benchmarks/time_tests.py " + " ".join(
        ["--tiers", *args.tiers]))
    print(text)
    if not args.no_write:
        update_section("test_tiers", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
