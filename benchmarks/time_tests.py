"""The test tiers, timed: wall time and outcome of ``make test-fast`` and ``make test``.

Runs each tier once through its make target (``make test-fast``, ``make test``: the Makefile
holds their workers and markers) in the repository, and writes ``docs/results/test_tiers.md``:
wall time, the pytest summary counts, the 1-minute load average before and after (the machine
may be shared: a loaded machine stretches every figure) and the slowest 30 test phases of the
last full run (``make test`` prints them). Not run by ``run_all.py`` (it would run the whole
suite inside ``make bench``).

With ``--ci-log FILE`` (repeatable) it also reads clean-clone CI runs: the output of
``(time bash .ci/run) > FILE 2>&1`` in a fresh clone (venv build, then ``make test``); each adds
a row with pytest's own wall time, its summary counts and the whole run's time (``real``, the
venv build included), and its slowest tests when it is the last full run.

The figures are saved beside the page (``docs/results/test_tiers.json``); ``--render`` writes
the page again from them without running anything.

Usage::

    .venv/bin/python benchmarks/time_tests.py [--tiers fast full] [--ci-log FILE ...]
        [--no-write]
    .venv/bin/python benchmarks/time_tests.py --render
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
import _results  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
#: tier -> its make target (the Makefile holds the pytest options of each: workers, markers)
TIERS = {"fast": "test-fast", "full": "test"}
#: What this script adds to the targets' pytest options.
PYTEST_ARGS = "-q -p no:cacheprovider"
_COUNT = re.compile(r"(\d+) (passed|failed|skipped|deselected|errors?|xfailed|xpassed)")
_PYTEST_SECONDS = re.compile(r" in ([0-9.]+)s")
_REAL = re.compile(r"^real\s+(\d+)m([0-9.]+)s", re.M)
_DURATION = re.compile(r"^([0-9.]+)s (call|setup|teardown)\s+(\S+)$")
#: Slowest tests listed on the page.
SLOWEST = 30


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


def slowest(output: str) -> list[list[object]]:
    """``[[seconds, phase, test id], ...]`` of pytest's ``--durations`` block, slowest first.

    >>> slowest("== slowest 30 durations ==\\n12.50s call     tests/a.py::test_x\\n"
    ...         "3.00s setup    tests/b.py::test_y\\n== 9 passed in 20.0s ==")
    [[12.5, 'call', 'tests/a.py::test_x'], [3.0, 'setup', 'tests/b.py::test_y']]
    """
    found = [[float(m.group(1)), m.group(2), m.group(3)] for m in
             (_DURATION.match(line.strip()) for line in output.splitlines()) if m]
    return sorted(found, key=lambda row: -float(row[0]))


def run_tier(name: str) -> dict[str, object]:
    """Run one tier through its make target; wall time (s), counts, exit status, load averages
    and the slowest tests the target prints."""
    load_before = os.getloadavg()[0]
    start = time.monotonic()
    proc = subprocess.run(["make", "-s", TIERS[name], f"PYTEST_ARGS={PYTEST_ARGS}"], cwd=REPO,
                          capture_output=True, text=True, check=False)
    seconds = time.monotonic() - start
    return {"tier": name, "seconds": seconds, "status": proc.returncode,
            "counts": summary_counts(proc.stdout), "load": (load_before, os.getloadavg()[0]),
            "tail": proc.stdout.strip().splitlines()[-1:] or [""],
            "slowest": slowest(proc.stdout)}


def read_ci_log(path: Path) -> dict[str, object]:
    """A clean-clone CI run from its log (module docstring): pytest's wall time (s) and
    counts, the whole run's time (s, venv build included) and the exit status if recorded.

    >>> import tempfile
    >>> log = Path(tempfile.mkdtemp()) / "cc.log"
    >>> _ = log.write_text("== 2 failed, 9 passed, 1 warning in 61.5s ==\\nreal\\t2m3.5s\\n")
    >>> r = read_ci_log(log)
    >>> r["seconds"], r["counts"], r["total"]
    (61.5, {'failed': 2, 'passed': 9}, 123.5)
    """
    text = path.read_text(encoding="utf-8", errors="replace")
    summary = [line for line in text.splitlines() if _COUNT.search(line)
               and _PYTEST_SECONDS.search(line)]
    if not summary:
        raise ValueError(f"{path}: no pytest summary line")
    real = _REAL.search(text)
    return {"tier": "full", "source": path.name,
            "seconds": float(_PYTEST_SECONDS.search(summary[-1]).group(1)),  # type: ignore[union-attr]
            "counts": summary_counts(summary[-1]),
            "total": 60 * int(real.group(1)) + float(real.group(2)) if real else None,
            "status": 0 if "failed" not in summary_counts(summary[-1]) else 1,
            "slowest": slowest(text)}


SECTION = "test_tiers"
TITLE = "Test tiers (`time_tests`)"
RENDER = "python benchmarks/time_tests.py --render"


def section(results: list[dict[str, object]]) -> str:
    """The figures of the ``test_tiers`` page (``docs/results/test_tiers.md``)."""
    rows = ["| tier | command | wall time | pytest exit | outcome | load avg before / after |",
            "| --- | --- | --- | --- | --- | --- |"]
    for r in results:
        counts = ", ".join(f"{n} {k}" for k, n in r["counts"].items())  # type: ignore[union-attr]
        if "load" in r:
            before, after = r["load"]  # type: ignore[misc]
            load, where = f"{before:.1f} / {after:.1f}", f"`make {TIERS[str(r['tier'])]}`"
        else:
            total = r["total"]
            load = "-"
            where = (f"`.ci/run` on a clean clone ({r['source']}"
                     + (f"; {float(total) / 60:.1f} min with the venv build)" if total else ")"))
        rows.append(f"| {r['tier']} | {where} | {float(r['seconds']) / 60:.1f} min | "
                    f"{r['status']} | {counts} | {load} |")
    body = ("Each tier run once on this worktree through its make target (the Makefile's "
            f"workers and markers, plus `{PYTEST_ARGS}`; the fast tier leaves out the `graph` "
            "and `slow` markers), and clean-clone CI runs read from their logs. Wall time from "
            "start to exit of pytest (the venv build not counted); the load average shows how "
            "busy the machine was.\n\n" + "\n".join(rows))
    timed = [r for r in results if r.get("slowest") and r["tier"] == "full"]
    if timed:
        last = timed[-1]
        name = last.get("source") or f"make {TIERS['full']}"
        lines = ["| # | seconds | phase | test |", "| --- | --- | --- | --- |"]
        lines += [f"| {i} | {float(sec):.1f} | {phase} | `{test}` |"
                  for i, (sec, phase, test) in enumerate(last["slowest"][:SLOWEST], 1)]  # type: ignore[index]
        body += (f"\n\nThe {SLOWEST} slowest test phases of the last full run ({name}; wall "
                 "seconds of each phase on its worker, as pytest's `--durations` prints them):"
                 "\n\n" + "\n".join(lines))
    return body


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tiers", nargs="*", choices=sorted(TIERS), default=["fast", "full"])
    parser.add_argument("--ci-log", type=Path, action="append", default=[],
                        help="log of a clean-clone `(time bash .ci/run)` run (repeatable)")
    _results.add_page_options(parser)
    args = parser.parse_args(argv)
    if args.render:
        print(_results.publish(SECTION, TITLE, section, RENDER))
        return 0
    results: list[dict[str, object]] = [read_ci_log(path) for path in args.ci_log]
    for name in args.tiers:
        print(f"== {name}", flush=True)
        results.append(run_tier(name))
        print(results[-1], flush=True)
    command = "python benchmarks/time_tests.py " + " ".join(
        ["--tiers", *args.tiers, *(f"--ci-log {p.name}" for p in args.ci_log)])
    print(section(results))
    if not args.no_write:
        print(_results.publish(SECTION, TITLE, section, RENDER, command=command, figures=results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
