"""Every push_core module has a test module of its own, tests/core/test_<module>.py (issue 21)."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_every_push_core_module_has_its_test_module() -> None:
    modules = {p.stem for p in (REPO / "src" / "push_core" / "push_core").glob("*.py")
               if p.stem != "__init__"}
    tests = {p.stem.removeprefix("test_") for p in Path(__file__).parent.glob("test_*.py")}
    assert len(modules) >= 20
    assert sorted(modules - tests) == []
