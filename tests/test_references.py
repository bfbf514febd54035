"""Comments and docs point at what a reader of the repository can open.

A reader of the project cannot open a ticket of the issue tracker or a section of the project
brief (SPEC), nor a file on the machine the text was written on. So no file of the tree (the
sources, tests, benchmarks, docs, Makefile, README and the dependency files) names an issue by
its number or a section of the brief: it states the reason itself, or names a section of a
document in the repository (``docs/design/stopping.md``). An upstream issue is a URL
(``https://github.com/<owner>/<repo>/issues/<n>``), which the rule lets through. No text names a
path outside the repository (a parent folder of the checkout, the machine's work folder, a
home folder); an upstream source is named as such (``upstream ros2_controllers jazzy``).
"""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: What is read: these folders (recursively) and files of the repository.
FOLDERS = ("src", "tests", "benchmarks", "docs", "ros_ws", ".ci")
FILES = ("Makefile", "README.md", "pyproject.toml", "requirements.txt", "constraints.txt")
#: Generated or installed trees inside those folders, not written by hand.
SKIPPED_PARTS = {"build", "install", "log", "__pycache__", ".venv", "node_modules"}
#: Text files larger than this are data (object files, weights), not prose.
MAX_BYTES = 2_000_000

#: (what, pattern) of a pointer a reader cannot follow.
RULES = (
    ("a tracker issue", re.compile(r"(?<![/\w])[Ii]ssues? *#?[0-9]+")),
    ("a section of the brief", re.compile(r"\bSPEC(?: *section| *sec\b| *§|\.md)")),
    ("a path outside the repository", re.compile(r"\.\./shared|(?<![\w.])/(?:work|root)/|"
                                                 r"(?<![\w.])/home/\w|(?<![\w.])/Users/\w")),
)


def problems(text: str, name: str) -> list[str]:
    """``name:line: <what>: <the line>`` for every pointer of :data:`RULES` in ``text``."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for what, pattern in RULES:
            if pattern.search(line):
                found.append(f"{name}:{number}: {what}: {line.strip()[:120]}")
    return found


def _files() -> list[Path]:
    paths = [REPO / f for f in FILES if (REPO / f).is_file()]
    for folder in FOLDERS:
        paths += [p for p in sorted((REPO / folder).rglob("*")) if p.is_file()
                  and not SKIPPED_PARTS & set(p.relative_to(REPO).parts)]
    return paths


def _text(path: Path) -> str | None:
    if path.stat().st_size > MAX_BYTES:
        return None
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError:  # a binary file (figures, weights)
        return None


def test_the_rules_by_hand() -> None:
    issue = "iss" + "ue"
    bad = [f"# see {issue} 15", f"({issue}s 16, 24)", f"{issue.capitalize()} 22's targets",
           f"{issue} #7", "SP" + "EC section 3", "../sha" + "red/ROBOT.md", "/wo" + "rk/x",
           "/ho" + "me/alice/x", "/ro" + "ot/.cache"]
    good = ["https://github.com/IntelRealSense/realsense-ros/" + issue + "s/2866",
            "the issue of a stale frame", "tissue 3", "docs/design/stopping.md",
            "upstream ros2_controllers jazzy", "~/reset", "/opt/ros/jazzy", "src/work/x"]
    assert [len(problems(line, "x")) for line in bad] == [1] * len(bad)
    assert [problems(line, "x") for line in good] == [[]] * len(good)
    assert problems("a\nb " + issue + " 3\n", "f.py") == [
        f"f.py:2: a tracker issue: b {issue} 3"]


def test_no_pointer_a_reader_cannot_follow() -> None:
    files = _files()
    assert len(files) > 200
    found = []
    for path in files:
        text = _text(path)
        if text is not None:
            found += problems(text, str(path.relative_to(REPO)))
    assert not found, "\n".join(found)
