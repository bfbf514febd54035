"""Shared helper of the benchmarks: figures as result pages, indexed by ``docs/RESULTS.md``.

Each benchmark section is one page, ``docs/results/<section_id>.md``, replaced as a whole by
:func:`update_section`, so benchmarks can run in any order. A page records the command that
produced it, the date, the commit (``git rev-parse --short HEAD``, ``-dirty`` when tracked files
other than the results differ from it), the machine (:func:`machine_info`), a one-line summary
and, where the benchmark keeps them, the file its figures were rendered from; then the figures
with their targets. :func:`format_section` writes the title, command, date and machine.

A benchmark that keeps its figures only in memory can save them beside its page with
:func:`save_record` (``docs/results/<section_id>.json``: the figures with the command, date,
machine and commit of the run) and render the page from that file with :func:`write_rendered`,
at the end of a run and again from its ``--render`` option without measuring (:func:`publish`
does both).

``docs/RESULTS.md`` is generated: one table row per page (title, summary, date, commit, link),
grouped by :data:`GROUPS`; every :func:`update_section` rebuilds it from the pages, and
``python benchmarks/_results.py --index`` does so without writing a page, and ``--import
OLD_RESULTS_MD`` turns the sections of a results file in the former single-file format into
pages. A page's summary is the caller's ``summary``, else the page's previous summary, else the
first sentence of its text.
"""

from __future__ import annotations

import argparse
import datetime
import fcntl
import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from pushbot.experiments.machine import machine_info  # noqa: F401 - re-exported

REPO = Path(__file__).resolve().parent.parent
RESULTS_PATH = REPO / "docs" / "RESULTS.md"
#: Paths whose changes do not make a measurement "-dirty": the results themselves.
RESULT_PATHS = ("docs/RESULTS.md", "docs/results")

#: The index's headings and the section ids under each, in order; other pages go last.
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Pushing model and simulation", ("bench_model", "bench_model_fidelity", "bench_sim")),
    ("Perception and estimation", ("eval_perception", "bench_perception", "eval_estimator",
                                   "bench_estimator")),
    ("Planning", ("bench_planner", "bench_lrn", "bench_lookahead_speed", "bench_lookahead",
                  "bench_lookahead_gt", "bench_adapt", "bench_adapt_filter")),
    ("Closed loop: the source's protocol (`eval_push`)", (
        "eval_push_full", "eval_push_gt", "eval_push_table51", "eval_push_table52",
        "eval_push_regions", "eval_push_regions_filter", "eval_push_ksweep",
        "eval_push_lookahead", "eval_push_support", "eval_push_limits")),
    ("Shape classes and Push-T", ("eval_shapes", "eval_shapes_variant", "eval_pusht")),
    ("The ROS graph, the CLI and recording", ("graph", "demo_repeat", "faults", "cli", "record",
                                              "view_relay")),
    ("Pushing with an arm", ("bench_arm_reach", "bench_arm_perception", "arm", "faults_arm")),
    ("The test suite and refactors", ("test_tiers", "same_trials")),
)
OTHER_GROUP = "Other results"

INDEX_HEADER = """# pushbot results

Measured figures, one page per benchmark section under [results/](results/), each written by
the script named on it (`make bench` runs them all) with its command, date, commit and machine.
Edit the scripts, not the pages: this index is generated from the pages by
`benchmarks/_results.py` whenever a page is written (`python benchmarks/_results.py --index`
rebuilds it). How the figures are used: the [architecture map](ARCHITECTURE.md).
"""

_ID = re.compile(r"[A-Za-z0-9_.-]+")
#: A line of the page header: ``- key: value``.
_FIELD = re.compile(r"^- (command|date|commit|machine|summary|data): (.*)$")
_FIELD_ORDER = ("command", "date", "commit", "machine", "summary", "data")


def today() -> str:
    """The current UTC date, ISO format (YYYY-MM-DD)."""
    return datetime.datetime.now(datetime.UTC).date().isoformat()


def format_section(title: str, command: str, body: str, *, date: str | None = None,
                   machine: str | None = None) -> str:
    """Markdown of one results section: title, command, date, machine, then ``body``.

    ``date`` and ``machine`` default to now and this machine; a page rendered again from saved
    figures passes the ones recorded with them.
    """
    return (
        f"## {title}\n\n"
        f"- command: `{command}`\n"
        f"- date: {date or today()}\n"
        f"- machine: {machine or machine_info()}\n\n"
        f"{body.strip()}\n"
    )


def current_commit(repo: Path = REPO) -> str:
    """``git rev-parse --short HEAD`` of ``repo``, with ``-dirty`` when a tracked file outside
    :data:`RESULT_PATHS` differs from it (untracked files are not counted, as in
    ``git describe --dirty``); ``unknown`` outside a git checkout."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=repo,
                              capture_output=True, text=True, check=True).stdout.strip()
        status = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no", "--", ".",
             *(f":(exclude){p}" for p in RESULT_PATHS)],
            cwd=repo, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("-dirty" if status.strip() else "")


class Page(NamedTuple):
    """One result page, parsed: title, header fields and the figures' text (a named tuple, not a
    dataclass: the source checkout's ``pushbot`` loads this file without registering a module)."""

    section_id: str
    title: str
    fields: dict[str, str]
    body: str

    def render(self) -> str:
        """The page's markdown."""
        header = "\n".join(f"- {key}: {self.fields[key]}" for key in _FIELD_ORDER
                           if key in self.fields)
        return (f"# {self.title}\n\n"
                f"Back to the [results index](../RESULTS.md). Written by the command below "
                f"through `benchmarks/_results.py`; edit the script, not this page.\n\n"
                f"{header}\n\n{self.body.strip()}\n")


def parse_section(section_id: str, markdown: str) -> Page:
    """Split a section's markdown (as :func:`format_section` writes it, or a page) into title,
    header fields and body; without a heading the title is ``section_id``."""
    lines = markdown.strip().splitlines()
    title = section_id
    if lines and re.match(r"^#{1,2} ", lines[0]):
        title = lines[0].split(" ", 1)[1].strip()
        lines = lines[1:]
    while lines and (not lines[0].strip() or lines[0].startswith("Back to the [results index]")):
        lines = lines[1:]
    fields: dict[str, str] = {}
    while lines and (match := _FIELD.match(lines[0])):
        fields[match[1]] = match[2].strip()
        lines = lines[1:]
    return Page(section_id, title, fields, "\n".join(lines).strip())


def first_sentence(body: str, limit: int = 160) -> str:
    """The first sentence of the first paragraph of ``body`` that is not a table or heading,
    cut at ``limit`` characters (a fallback summary)."""
    for paragraph in re.split(r"\n\s*\n", body):
        text = " ".join(paragraph.split())
        if text and not text.startswith(("|", "#", "<!--")):
            sentence = re.split(r"(?<=\.)\s", text, maxsplit=1)[0]
            return sentence if len(sentence) <= limit else sentence[:limit - 3].rstrip() + "..."
    return ""


def pages_dir(path: Path = RESULTS_PATH) -> Path:
    """The folder of the result pages of the index ``path``: ``results/`` beside it."""
    return path.parent / "results"


def page_path(section_id: str, path: Path = RESULTS_PATH) -> Path:
    """The page of ``section_id`` for the index ``path``."""
    return pages_dir(path) / f"{section_id}.md"


def read_pages(path: Path = RESULTS_PATH) -> list[Page]:
    """Every result page beside the index ``path``, parsed, by section id."""
    folder = pages_dir(path)
    return [parse_section(p.stem, p.read_text(encoding="utf-8"))
            for p in sorted(folder.glob("*.md"))] if folder.is_dir() else []


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def render_index(pages: list[Page]) -> str:
    """The markdown of ``docs/RESULTS.md`` for ``pages``: one table per group of :data:`GROUPS`
    (unknown sections last), each row title (linked), summary, date and commit."""
    by_id = {page.section_id: page for page in pages}
    groups = [(heading, [i for i in ids if i in by_id]) for heading, ids in GROUPS]
    known = {i for _heading, ids in GROUPS for i in ids}
    groups.append((OTHER_GROUP, sorted(set(by_id) - known)))
    parts = [INDEX_HEADER]
    for heading, ids in groups:
        if not ids:
            continue
        rows = ["| result | what it measures | date | commit |", "| --- | --- | --- | --- |"]
        for i in ids:
            page = by_id[i]
            rows.append(f"| [{_cell(page.title)}](results/{i}.md) | "
                        f"{_cell(page.fields.get('summary', ''))} | "
                        f"{_cell(page.fields.get('date', ''))} | "
                        f"{_cell(page.fields.get('commit', ''))} |")
        parts.append(f"## {heading}\n\n" + "\n".join(rows) + "\n")
    return "\n".join(parts)


def _replace(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text, encoding="utf-8")
    tmp.replace(path)


class _Lock:
    """Benchmarks may run concurrently: an advisory lock on the index's folder serialises each
    page write with its index rebuild (the files are replaced by renames, so they cannot hold
    the lock themselves)."""

    def __init__(self, path: Path) -> None:
        self.folder = path.parent

    def __enter__(self) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        self.fd = os.open(self.folder, os.O_RDONLY)
        fcntl.flock(self.fd, fcntl.LOCK_EX)

    def __exit__(self, *exc: object) -> None:
        os.close(self.fd)  # releases the lock


def write_index(path: Path = RESULTS_PATH) -> None:
    """Rebuild the index ``path`` from the pages beside it."""
    with _Lock(path):
        _replace(path, render_index(read_pages(path)))


def update_section(section_id: str, markdown: str, path: Path = RESULTS_PATH, *,
                   summary: str | None = None, data: str | None = None,
                   commit: str | None = None) -> Path:
    """Write (or replace) the result page of one section and rebuild the index.

    Parameters
    ----------
    section_id : str
        Identifier of the section, the page's file name: letters, digits, ``_``, ``-``, ``.``.
    markdown : str
        The section: its title, then the header :func:`format_section` writes, then the
        figures; a ``- commit:`` line is added after the date unless the header has one.
    path : pathlib.Path
        The index file; the page goes to ``results/<section_id>.md`` beside it.
    summary : str, optional
        One line saying what the page measures, for the index; default: the page's previous
        summary, else the first sentence of its text.
    data : str, optional
        Markdown naming the file the figures were rendered from and the command that renders
        the page again from it.
    commit : str, optional
        The commit measured; default :func:`current_commit` (a page rendered again from saved
        figures passes the commit recorded with them).

    Returns
    -------
    pathlib.Path
        The page written.

    Raises
    ------
    ValueError
        If ``section_id`` has other characters.
    """
    if not _ID.fullmatch(section_id):
        raise ValueError(f"section_id must match [A-Za-z0-9_.-]+, got {section_id!r}")
    path = Path(path)
    page = parse_section(section_id, markdown)
    fields = dict(page.fields)
    fields.setdefault("commit", commit or current_commit())
    target = page_path(section_id, path)
    with _Lock(path):
        previous = parse_section(section_id, target.read_text(encoding="utf-8")) \
            if target.exists() else None
        fields["summary"] = " ".join((summary or fields.get("summary")
                                      or (previous.fields.get("summary") if previous else None)
                                      or first_sentence(page.body)).split())
        if data:
            fields["data"] = " ".join(data.split())
        target.parent.mkdir(parents=True, exist_ok=True)
        _replace(target, Page(section_id, page.title, fields, page.body).render())
        _replace(path, render_index(read_pages(path)))
    return target


def record_path(section_id: str, path: Path | None = None) -> Path:
    """The saved figures of ``section_id`` for the index ``path`` (default
    :data:`RESULTS_PATH`): beside its page."""
    return pages_dir(Path(path) if path else RESULTS_PATH) / f"{section_id}.json"


def save_record(section_id: str, command: str, figures: object,
                path: Path | None = None) -> dict:
    """Save a run's figures beside its page, with what :func:`format_section` and
    :func:`update_section` record about the run.

    Parameters
    ----------
    section_id : str
        The section (as for :func:`update_section`).
    command : str
        The command that measured them.
    figures : object
        JSON-serialisable figures: what the benchmark renders its page from.
    path : pathlib.Path, optional
        The index file (default :data:`RESULTS_PATH`); the record goes to
        ``results/<section_id>.json`` beside it.

    Returns
    -------
    dict
        ``{"section", "command", "date", "machine", "commit", "figures"}`` as written.
    """
    if not _ID.fullmatch(section_id):
        raise ValueError(f"section_id must match [A-Za-z0-9_.-]+, got {section_id!r}")
    record = {"section": section_id, "command": command, "date": today(),
              "machine": machine_info(), "commit": current_commit(), "figures": figures}
    target = record_path(section_id, path)
    target.parent.mkdir(parents=True, exist_ok=True)
    _replace(target, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return record


def load_record(section_id: str, path: Path | None = None) -> dict:
    """The record :func:`save_record` wrote for ``section_id``.

    Raises
    ------
    FileNotFoundError
        If the section has no saved figures.
    """
    return json.loads(record_path(section_id, path).read_text(encoding="utf-8"))


def write_rendered(section_id: str, title: str, body: str, record: dict, render_command: str,
                   path: Path | None = None, *, summary: str | None = None) -> Path:
    """Write the page of ``record`` (from :func:`save_record` or :func:`load_record`): its
    command, date, machine and commit, not those of this call, and a ``data`` line naming the
    saved figures and ``render_command``, which writes the page again from them."""
    markdown = format_section(title, record["command"], body, date=record["date"],
                              machine=record["machine"])
    data = (f"[`{section_id}.json`]({section_id}.json), rendered by `{render_command}`")
    return update_section(section_id, markdown, Path(path) if path else RESULTS_PATH,
                          summary=summary, data=data, commit=record["commit"])


def add_page_options(parser: argparse.ArgumentParser) -> None:
    """The ``--no-write`` and ``--render`` options of a benchmark that saves its figures."""
    parser.add_argument("--no-write", action="store_true", help="do not write the result page")
    parser.add_argument("--render", action="store_true",
                        help="write the page again from the saved figures; measure nothing")


def publish(section_id: str, title: str, render: Callable[[Any], str], render_command: str, *,
            command: str | None = None, figures: object = None, path: Path | None = None,
            summary: str | None = None) -> Path:
    """Save ``figures`` measured by ``command`` (:func:`save_record`) and write the page
    ``render`` makes of them (:func:`write_rendered`); without ``command``, write the page again
    from the figures saved before (a benchmark's ``--render``)."""
    record = (save_record(section_id, command, figures, path) if command is not None
              else load_record(section_id, path))
    return write_rendered(section_id, title, render(record["figures"]), record, render_command,
                          path, summary=summary)


#: A section of the single-file results format this module replaced.
_OLD_SECTION = re.compile(r"<!-- BEGIN ([A-Za-z0-9_.-]+) -->\n(.*?)\n<!-- END \1 -->", re.DOTALL)


def import_sections(text: str, sections: list[str] | None = None, commit: str | None = None,
                    path: Path | None = None) -> list[str]:
    """Write pages for the sections of a results file in the old single-file format
    (``<!-- BEGIN id -->`` ... ``<!-- END id -->``, as a branch made before the pages wrote it),
    figures and dates as they are.

    Parameters
    ----------
    text : str
        The old file's text.
    sections : list of str, optional
        The sections to import; default: those that have no page yet.
    commit : str, optional
        The commit line of the imported pages; default ``not recorded (imported)``.
    path : pathlib.Path, optional
        The index file (default :data:`RESULTS_PATH`).

    Returns
    -------
    list of str
        The sections written.
    """
    index = Path(path) if path else RESULTS_PATH
    found = {m[1]: m[2] for m in _OLD_SECTION.finditer(text)}
    wanted = sections if sections is not None else [
        s for s in found if not page_path(s, index).exists()]
    missing = [s for s in wanted if s not in found]
    if missing:
        raise ValueError(f"no such section in the old file: {', '.join(missing)}")
    for section_id in wanted:
        update_section(section_id, found[section_id], index,
                       commit=commit or "not recorded (imported)")
    return wanted


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Rebuild docs/RESULTS.md from the result pages.")
    parser.add_argument("--index", action="store_true", help="rebuild the index (the default)")
    parser.add_argument("--import", dest="old", type=Path, metavar="OLD_RESULTS_MD",
                        help="write pages for the sections of a results file in the old "
                             "single-file format (default: those without a page), then the index")
    parser.add_argument("--sections", nargs="+", help="with --import: these sections")
    parser.add_argument("--commit", help="with --import: the commit line of the imported pages")
    args = parser.parse_args(argv)
    if args.old:
        written = import_sections(args.old.read_text(encoding="utf-8"), args.sections,
                                  args.commit)
        print(f"imported {len(written)} sections: {' '.join(written) or '-'}")
    write_index()
    print(f"wrote {RESULTS_PATH.relative_to(REPO)} from {len(read_pages())} pages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
