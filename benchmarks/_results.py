"""Shared helper of the benchmarks: write measured figures into ``docs/RESULTS.md``.

Each benchmark owns one section of ``docs/RESULTS.md``, delimited by
``<!-- BEGIN section_id -->`` / ``<!-- END section_id -->``, and replaces only that section, so
benchmarks can be run in any order. A section records the command that produced it, the date,
the machine (:func:`machine_info`) and the figures with their targets; :func:`format_section`
writes that header.
"""

from __future__ import annotations

import datetime
import fcntl
import os
import re
from pathlib import Path

from pushbot.experiments.machine import machine_info  # noqa: F401 - re-exported

RESULTS_PATH = Path(__file__).resolve().parent.parent / "docs" / "RESULTS.md"

HEADER = """# pushbot results

Measured figures, written by the scripts in `benchmarks/` (`make bench` runs them all). Each
section is replaced in place by the script named in it; edit the scripts, not the figures.
"""


def today() -> str:
    """The current UTC date, ISO format (YYYY-MM-DD)."""
    return datetime.datetime.now(datetime.UTC).date().isoformat()


def format_section(title: str, command: str, body: str) -> str:
    """Markdown of one results section: title, command, date, machine, then ``body``."""
    return (
        f"## {title}\n\n"
        f"- command: `{command}`\n"
        f"- date: {today()}\n"
        f"- machine: {machine_info()}\n\n"
        f"{body.strip()}\n"
    )


def update_section(section_id: str, markdown: str, path: Path = RESULTS_PATH) -> None:
    """Replace (or append) one delimited section of the results file.

    Parameters
    ----------
    section_id : str
        Identifier of the section: letters, digits, ``_``, ``-`` and ``.``.
    markdown : str
        New content of the section (without the delimiters).
    path : pathlib.Path
        The results file; created with a short header if missing.

    Raises
    ------
    ValueError
        If ``section_id`` has other characters or ``markdown`` contains a section delimiter.
    """
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", section_id):
        raise ValueError(f"section_id must match [A-Za-z0-9_.-]+, got {section_id!r}")
    if "<!-- BEGIN " in markdown or "<!-- END " in markdown:
        raise ValueError("markdown must not contain section delimiters")
    begin, end = f"<!-- BEGIN {section_id} -->", f"<!-- END {section_id} -->"
    block = f"{begin}\n{markdown.strip()}\n{end}"
    path.parent.mkdir(parents=True, exist_ok=True)
    # Benchmarks may run concurrently: serialise the read-modify-write with an advisory lock on
    # the directory (the file itself is replaced by a rename, so it cannot hold the lock).
    lock = os.open(path.parent, os.O_RDONLY)
    try:
        fcntl.flock(lock, fcntl.LOCK_EX)
        text = path.read_text(encoding="utf-8") if path.exists() else HEADER
        pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.DOTALL)
        if pattern.search(text):
            text = pattern.sub(lambda _: block, text, count=1)
        else:
            text = text.rstrip("\n") + "\n\n" + block + "\n"
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text, encoding="utf-8")
        tmp.replace(path)
    finally:
        os.close(lock)  # releases the lock
