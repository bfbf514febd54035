"""Run every benchmark in this folder (``bench_*.py``), one process each, in name order.

Each benchmark writes its own page under ``docs/results/`` (indexed by ``docs/RESULTS.md``).
Extra arguments are passed to every benchmark (for example ``--no-write``). Exits non-zero if
any benchmark failed.

Usage::

    .venv/bin/python benchmarks/run_all.py [args passed to each benchmark]
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    here = Path(__file__).resolve().parent
    failed = []
    for script in sorted(here.glob("bench_*.py")):
        print(f"== {script.name}", flush=True)
        if subprocess.run([sys.executable, str(script), *args], check=False).returncode != 0:
            failed.append(script.name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
