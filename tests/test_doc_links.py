"""Every link of the documentation resolves, so a reader can follow it.

- Every relative Markdown link and image in ``README.md`` and ``docs/**/*.md`` names a file or
  folder that exists, and its ``#anchor``, on a Markdown file, is a heading of that file by
  GitHub's rule (:func:`anchors`). Links inside code (fenced blocks, backtick spans) are text,
  not links; ``http(s)``/``mailto`` links are not followed.
- Every ``docs/...md`` path (with its ``#anchor``, if any) named in ``src/``, ``tests/`` and
  ``benchmarks/`` exists, and a section named after it in quotes (``docs/<page>.md, "Section"``) is
  the start of a heading of that file.
- Every design page is linked from the map, so any decision is two clicks from the README
  (README -> ``docs/ARCHITECTURE.md`` -> ``docs/design/<topic>.md``), and the README links the
  map, the robot guide, the CLI guide and the results index.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
#: ``[text](target)`` or ``![alt](target)``, an optional ``"title"`` after the target.
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
#: ``docs/....md`` with an optional anchor, as code and comments name the pages.
DOC_PATH = re.compile(r"\bdocs/(?:[\w-][\w.-]*/)*[\w-][\w.-]*\.md(?:#[\w-]+)?")
#: A quoted section name right after such a path: ``docs/<page>.md, "Section"``.
QUOTED_SECTION = re.compile(DOC_PATH.pattern + r',?\s+"([^"]+)"')
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"", re.I)
SCANNED_SUFFIXES = {".py", ".md", ".yaml", ".yml", ".xml", ".cfg", ".toml", ".txt", ".rviz"}


def _outside_code(text: str) -> Iterator[tuple[int, str]]:
    """``(line number, line)`` of the lines outside fenced code blocks, backtick spans blanked."""
    fence: str | None = None
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.lstrip()
        if fence is None and stripped.startswith(("```", "~~~")):
            fence = stripped[:3]
            continue
        if fence is not None:
            if stripped.startswith(fence):
                fence = None
            continue
        yield number, re.sub(r"(`+)(?:(?!\1).)+?\1", lambda m: " " * len(m[0]), line)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading's text: the text as rendered (inline code, emphasis, links
    and HTML reduced to their text), lower case, every character but letters, digits, ``_``,
    ``-`` and spaces dropped, each space a ``-``.
    """
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"<[^>]+>", "", text)
    text = re.sub(r"(`+)(.+?)\1", r"\2", text)
    text = re.sub(r"(\*+|(?<!\w)_+|_+(?!\w))", "", text)
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def headings(text: str) -> list[str]:
    """The text of every heading of a Markdown file outside code, as written."""
    found, fence = [], None
    for line in text.splitlines():
        stripped = line.lstrip()
        if stripped.startswith(("```", "~~~")) and (fence is None or stripped.startswith(fence)):
            fence = stripped[:3] if fence is None else None
            continue
        if fence is None and (match := HEADING.match(line)):
            found.append(match[2])
    return found


def anchors(text: str) -> set[str]:
    """The anchors GitHub gives a Markdown file: one per heading outside code (a repeated slug
    gets ``-1``, ``-2``, ...) and every ``<a name=...>`` / ``<a id=...>``."""
    found: set[str] = set(HTML_ANCHOR.findall(text))
    seen: Counter[str] = Counter()
    for heading in headings(text):
        base = slug(heading)
        found.add(base if not seen[base] else f"{base}-{seen[base]}")
        seen[base] += 1
    return found


def broken_target(source: Path, target: str, root: Path) -> str | None:
    """None when ``target`` (a path relative to ``source``'s folder, or ``/...`` from ``root``,
    with an optional ``#anchor``) resolves, else why not."""
    path_part, _, anchor = target.partition("#")
    if path_part.startswith("/"):
        path = root / path_part.lstrip("/")
    else:
        path = (source.parent / path_part) if path_part else source
    if not path.exists():
        return f"{path_part} does not exist"
    if anchor and path.suffix == ".md" and path.is_file() and \
            anchor not in anchors(path.read_text(encoding="utf-8")):
        return f"{path.name} has no heading with the anchor #{anchor}"
    return None


def broken_links(path: Path, root: Path = REPO) -> list[str]:
    """``file:line: target: why`` of every relative link of the Markdown file ``path`` that does
    not resolve."""
    problems = []
    for number, line in _outside_code(path.read_text(encoding="utf-8")):
        for target in LINK.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, https:, mailto:
                continue
            why = broken_target(path, target, root)
            if why:
                problems.append(f"{path.relative_to(root)}:{number}: {target}: {why}")
    return problems


def broken_doc_paths(path: Path, root: Path = REPO) -> list[str]:
    """``file:line: path: why`` of every ``docs/...md`` path named in ``path`` that does not
    resolve from ``root``."""
    problems = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        for target in DOC_PATH.findall(line):
            why = broken_target(root / "README.md", target, root)
            if why:
                problems.append(f"{path.relative_to(root)}:{number}: {target}: {why}")
        for match in QUOTED_SECTION.finditer(line):
            page = root / match[0].split(",")[0].split()[0].partition("#")[0]
            titles = [slug(h) for h in headings(page.read_text(encoding="utf-8"))] \
                if page.is_file() else []
            if page.is_file() and not any(h.startswith(slug(match[1])) for h in titles):
                problems.append(f"{path.relative_to(root)}:{number}: {match[0]}: "
                                f"{page.name} has no heading starting {match[1]!r}")
    return problems


def markdown_files(root: Path = REPO) -> list[Path]:
    return [root / "README.md", *sorted((root / "docs").rglob("*.md"))]


def named_files(root: Path = REPO) -> list[Path]:
    """The text files of ``src/``, ``tests/`` and ``benchmarks/`` (build output left out)."""
    return [p for folder in ("src", "tests", "benchmarks")
            for p in sorted((root / folder).rglob("*"))
            if p.is_file() and p.suffix in SCANNED_SUFFIXES and "build" not in p.parts
            and "__pycache__" not in p.parts]


def test_anchors_follow_githubs_rule() -> None:
    titles = ("Units of eq. (5.1)", "The `pushbot` CLI", "push_core as a library; Push-T",
              "[Faults](faults.md) and **recovery**", "~/reset", "goal --wait",
              "Parameters and main()")
    assert [slug(h) for h in titles] == [
        "units-of-eq-51", "the-pushbot-cli", "push_core-as-a-library-push-t",
        "faults-and-recovery", "reset", "goal---wait", "parameters-and-main"]
    text = '# A\n## Notes\n```\n# not a heading\n```\n## Notes\n<a id="x"></a>\n## Notes\n'
    assert anchors(text) == {"a", "notes", "notes-1", "notes-2", "x"}


def test_the_checker_finds_broken_links_and_anchors(tmp_path: Path) -> None:
    (tmp_path / "guide").mkdir()
    (tmp_path / "guide" / "topic.md").write_text(
        "# Topic\n\n## The rule\n\n## The rule\n\n## `code` and **bold**\n")
    readme = tmp_path / "README.md"
    readme.write_text(
        "[ok](guide/topic.md#the-rule) [second](guide/topic.md#the-rule-1)\n"
        "[rendered](guide/topic.md#code-and-bold) [web](https://example.org/x#y) [dir](guide/)\n"
        "[no file](guide/gone.md) [no anchor](guide/topic.md#the-rules)\n"
        "`[in code](guide/gone.md)`\n```\n[in a fence](nowhere.md)\n```\n"
        "![image](guide/figure.png) [self](#nothing-here)\n")
    problems = broken_links(readme, tmp_path)
    assert [p.split(": ", 1)[0] for p in problems] == [
        "README.md:3", "README.md:3", "README.md:8", "README.md:8"], problems
    assert "guide/gone.md does not exist" in problems[0]
    assert "topic.md has no heading with the anchor #the-rules" in problems[1]
    assert "guide/figure.png does not exist" in problems[2]
    assert "README.md has no heading with the anchor #nothing-here" in problems[3]
    # The same pages under docs/, named by code; the paths are put together at run time so
    # that this file itself names none.
    (tmp_path / "guide").rename(tmp_path / "docs")
    docs = "docs" + "/"
    code = tmp_path / "src" / "module.py"
    code.parent.mkdir()
    code.write_text(f'"""Rules: {docs}topic.md#the-rule, {docs}gone.md and {docs}topic.md#nope;'
                    f' {docs}.../x.md is no path.\n{docs}topic.md, "The rule" and {docs}topic.md,'
                    f' "Rules" (a section that is not there)."""\n')
    assert [p.split(": ", 2)[1] for p in broken_doc_paths(code, tmp_path)] == [
        f"{docs}gone.md", f"{docs}topic.md#nope", f'{docs}topic.md, "Rules"'], \
        broken_doc_paths(code, tmp_path)


def test_every_relative_link_resolves() -> None:
    files = markdown_files()
    assert len(files) > 40  # README, the guides, the map, the design and result pages
    problems = [p for path in files for p in broken_links(path)]
    assert not problems, "\n".join(problems)


def test_every_docs_path_named_in_the_code_exists() -> None:
    files = named_files()
    problems = [p for path in files for p in broken_doc_paths(path)]
    assert not problems, "\n".join(problems)
    assert sum(len(DOC_PATH.findall(p.read_text(encoding="utf-8"))) for p in files) > 50


def test_every_design_page_is_linked_from_the_map_and_the_readme_says_where_to_start() -> None:
    links = set(LINK.findall((DOCS / "ARCHITECTURE.md").read_text(encoding="utf-8")))
    linked = {target.partition("#")[0] for target in links}
    pages = {f"design/{p.name}" for p in (DOCS / "design").glob("*.md")}
    assert pages and not pages - linked, f"not linked from the map: {sorted(pages - linked)}"
    readme = {t.partition("#")[0] for t in LINK.findall((REPO / "README.md").read_text())}
    assert {"docs/ARCHITECTURE.md", "docs/ROBOT.md", "docs/CLI.md", "docs/RESULTS.md"} <= readme
