"""Every first-party dotted name the documentation quotes resolves.

Scanned: ``README.md``, ``docs/**/*.md`` (the map, design and result pages) and the docstrings
of every module, class and function under ``src/`` (launch files included). A name counts when
it is quoted in backticks (Markdown `` `x` ``, reStructuredText ````x````, Sphinx roles such as
``:class:`~x```) and starts with a first-party package followed by at least one dotted part
(``push_core.planner.Planner``, ``pushbot.protocol.Trial.goal``); file names
(``pushbot.launch.py``) are not names. A name
resolves when its longest importable prefix is a module and the rest are attributes (a
dataclass field or an annotated attribute counts as an attribute of its class). Nothing is
skipped: a moved module fails here until every reference to it is updated.
"""

from __future__ import annotations

import ast
import importlib
import re
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGES = ("push_core", "push_ros", "sim_bridge", "push_perception", "push_estimator",
            "push_planner", "push_executor", "pushbot_bringup", "pushbot")
_PACKAGE = "|".join(sorted(PACKAGES, key=len, reverse=True))
#: A first-party dotted name at the start of a backtick-quoted span (after an optional ``~``).
NAME = re.compile(rf"`{{1,2}}~?((?:{_PACKAGE})(?:\.[A-Za-z_]\w*)+)(?=[`(\[ ,:])")
#: Suffixes that make a dotted word a file name, not a Python name.
FILE_SUFFIXES = {"py", "md", "yaml", "yml", "json", "pt", "xml", "cfg", "txt", "csv", "gif"}


def names_in(text: str) -> Iterator[str]:
    """The first-party dotted names quoted in ``text`` (module docstring), file names left out.

    Examples
    --------
    >>> list(names_in("see `push_core.planner.Planner` and ``pushbot.launch.py``"))
    ['push_core.planner.Planner']
    """
    for match in NAME.finditer(text):
        name = match[1]
        if name.rsplit(".", 1)[1] not in FILE_SUFFIXES:
            yield name


def _docstrings(path: Path) -> Iterator[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                yield doc


def quoted_names() -> dict[str, set[str]]:
    """``{name: {where it is quoted}}`` over the README, docs/**/*.md and the docstrings of src/."""
    found: dict[str, set[str]] = {}
    sources: list[tuple[str, str]] = [
        (str(p.relative_to(REPO)), p.read_text(encoding="utf-8"))
        for p in [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]]
    for path in sorted((REPO / "src").rglob("*.py")):
        sources += [(str(path.relative_to(REPO)), doc) for doc in _docstrings(path)]
    for where, text in sources:
        for name in names_in(text):
            found.setdefault(name, set()).add(where)
    return found


def _has_attribute(owner: Any, attribute: str) -> tuple[bool, Any]:
    if hasattr(owner, attribute):
        return True, getattr(owner, attribute)
    if attribute in getattr(owner, "__dataclass_fields__", {}) or \
            attribute in getattr(owner, "__annotations__", {}):
        return True, None
    return False, None


def resolve(name: str) -> str | None:
    """None when ``name`` resolves, else why not."""
    parts = name.split(".")
    module: ModuleType | None = None
    for cut in range(len(parts), 0, -1):
        try:
            module = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError as exc:
            if exc.name is not None and not ".".join(parts[:cut]).startswith(exc.name):
                return f"importing {'.'.join(parts[:cut])} fails: {exc}"
            continue
        break
    if module is None:
        return "no importable module"
    owner: Any = module
    for attribute in parts[cut:]:
        ok, owner = _has_attribute(owner, attribute)
        if not ok:
            return f"{'.'.join(parts[:parts.index(attribute)])} has no {attribute!r}"
        if owner is None:  # a field: nothing further to look into
            break
    return None


def test_the_pattern_finds_quoted_names_only() -> None:
    text = ("`push_core.planner.Planner` ``push_ros.stamps`` :class:`~push_core.episode.Engine` "
            "`push_core.planner.reached(pose, goal)` push_core.geometry (unquoted) "
            "`pushbot_bringup/launch` ``pushbot.launch.py`` `push_corex.y` `pushbot` "
            "``push_executor.parameters.PARAMETERS``")
    assert list(names_in(text)) == ["push_core.planner.Planner", "push_ros.stamps",
                                    "push_core.episode.Engine", "push_core.planner.reached",
                                    "push_executor.parameters.PARAMETERS"]


def test_resolve_tells_a_missing_attribute_from_a_missing_module() -> None:
    assert resolve("push_core.planner.Planner") is None
    assert resolve("push_core.planner.PlannerConfig.k") is None  # a dataclass field
    assert "no 'NoSuchThing'" in (resolve("push_core.planner.NoSuchThing") or "")
    assert "has no 'closed_loop'" in (resolve("push_planner.closed_loop") or "")


@pytest.mark.slow
def test_every_quoted_first_party_name_resolves() -> None:
    names = quoted_names()
    assert len(names) > 150  # the scan sees the documentation (212 names on 2026-12-03)
    broken = {name: (why, sorted(names[name])) for name in sorted(names)
              if (why := resolve(name)) is not None}
    assert not broken, "\n".join(f"{name}: {why} (quoted in {', '.join(where)})"
                                 for name, (why, where) in broken.items())
