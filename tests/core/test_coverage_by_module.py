"""Every push_core module has a test module of its own.

A module ``push_core/<name>.py`` is tested in ``tests/core/test_<name>.py``; a module of a
subpackage, ``push_core/<package>/<name>.py``, in ``test_<name>.py`` or
``test_<package>_<name>.py``, and the subpackage's public face (its ``__init__``) in
``test_<package>.py``.
"""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
ROOT = REPO / "src" / "push_core" / "push_core"


def expected_test_names(module: Path) -> set[str]:
    """The test module stems (without ``test_``) any of which covers ``module``."""
    parts = module.relative_to(ROOT).with_suffix("").parts
    if len(parts) == 1:
        return {parts[0]}
    package, name = parts[-2], parts[-1]
    return {package} if name == "__init__" else {name, f"{package}_{name}"}


def test_expected_test_names() -> None:
    assert expected_test_names(ROOT / "model.py") == {"model"}
    assert expected_test_names(ROOT / "estimator" / "__init__.py") == {"estimator"}
    assert expected_test_names(ROOT / "estimator" / "config.py") == {"config", "estimator_config"}


def test_every_push_core_module_has_its_test_module() -> None:
    modules = [p for p in ROOT.rglob("*.py") if p != ROOT / "__init__.py"]
    tests = {p.stem.removeprefix("test_") for p in Path(__file__).parent.glob("test_*.py")}
    assert len(modules) >= 20
    assert sorted(str(p.relative_to(ROOT)) for p in modules
                  if not expected_test_names(p) & tests) == []
