"""The layering of docs/ARCHITECTURE.md#packages, enforced over every first-party import.

Every kind of import counts, because each one ties two modules together for a reader and for
a refactor: a module-level ``import``, a lazy one inside a function, one under
``if TYPE_CHECKING:`` (it never runs, but the annotation still names the other module), and an
import by name (``importlib.import_module`` / ``__import__``: every string in that module that
names a first-party module, such as the CLI's command table). Checked:

- the direction ``push_core <- push_ros <- node packages <- pushbot``: a package imports only
  itself and packages of a lower layer; the node packages never import each other; the
  deployment package ``pushbot_bringup`` (launch file included) imports no ``pushbot`` module
  and no node package, only ``push_ros``;
- inside ``pushbot``, the direction between its subpackages:
  ``ros2cli <- viz <- runner <- experiments <- pushbot.cli``, with no exception;
- a room (a package, or a ``pushbot`` subpackage) uses another only through its public names:
  no name with a leading underscore, and only names of the target module's ``__all__`` where it
  has one;
- every first-party package a package imports is declared in its ``package.xml``;
- no import cycle among first-party modules.

The checks run on a :class:`Tree` read from a source folder, so the tests below also run them
on small hand-made trees with a known cycle or a known upward arrow.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
#: package -> layer; a package may import packages of a lower layer (and itself).
LAYERS = {"push_core": 0, "push_ros": 1, "sim_bridge": 2, "push_perception": 2,
          "push_estimator": 2, "push_planner": 2, "push_executor": 2, "pushbot_bringup": 2,
          "pushbot": 3}
#: Extra limits beyond the layers.
ALLOWED_BELOW = {"pushbot_bringup": {"push_ros"}}
#: ``pushbot`` subpackage -> layer inside ``pushbot``; the top-level modules (``pushbot.cli``,
#: ``pushbot.cli_reference``, which load the commands by name) are above them all.
PUSHBOT_LAYERS = {"ros2cli": 0, "viz": 1, "runner": 2, "experiments": 3}
TOP = len(PUSHBOT_LAYERS)
_BY_NAME = {"import_module", "__import__"}


@dataclass(frozen=True)
class Import:
    """One import of a first-party module: ``target`` (a module), ``name`` (the name taken from
    it by ``from target import name``; None for a whole module) and the source line."""

    target: str
    name: str | None
    line: int


@dataclass
class Tree:
    """The first-party modules of a source folder ``src`` and their imports.

    ``modules``: module name -> (package, file); ``imports``: module name -> its imports of
    other first-party modules; ``exports``: module name -> its ``__all__`` (None without one).
    """

    src: Path
    modules: dict[str, tuple[str, Path]]
    imports: dict[str, list[Import]] = field(default_factory=dict)
    exports: dict[str, set[str] | None] = field(default_factory=dict)

    def edges(self) -> dict[str, set[str]]:
        """module -> the other first-party modules it imports."""
        return {m: {i.target for i in found if i.target != m}
                for m, found in self.imports.items()}


def _module_name(path: Path, package_dir: Path) -> str:
    rel = path.relative_to(package_dir).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _find_modules(src: Path, packages: dict[str, int]) -> dict[str, tuple[str, Path]]:
    """module name -> (package, file) for every module under src/<package>/<package>/ and the
    bringup launch files (as ``pushbot_bringup.launch.<name>``)."""
    modules: dict[str, tuple[str, Path]] = {}
    for package in packages:
        root = src / package
        for path in sorted((root / package).rglob("*.py")):
            modules[_module_name(path, root)] = (package, path)
        for path in sorted((root / "launch").glob("*.py")):
            modules[f"{package}.launch.{path.stem.replace('.', '_')}"] = (package, path)
    return modules


def _resolve(name: str, modules: dict[str, tuple[str, Path]]) -> str | None:
    """The first-party module ``name`` refers to (``a.b.c`` may be ``a.b`` + attribute c)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _raw_imports(tree: ast.Module, module: str, is_package: bool
                 ) -> Iterator[tuple[str, str | None, int]]:
    """(module, name or None, line) of every import statement, wherever it stands."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, None, node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".")
                keep = len(parts) - node.level + (1 if is_package else 0)
                base = ".".join(parts[:keep] + ([base] if base else []))
            for alias in node.names:
                yield base, alias.name, node.lineno


def _imports_by_name(tree: ast.Module, modules: dict[str, tuple[str, Path]]
                     ) -> Iterator[tuple[str, str | None, int]]:
    """A module that imports by name imports every first-party module one of its strings
    names exactly (the name may be built anywhere in the module: a table, a constant)."""
    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call)
             and (getattr(n.func, "attr", None) in _BY_NAME
                  or getattr(n.func, "id", None) in _BY_NAME)]
    if not calls:
        return
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                and node.value in modules:
            yield node.value, None, node.lineno


def _exports(tree: ast.Module) -> set[str] | None:
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            try:
                return set(ast.literal_eval(node.value))
            except ValueError:
                return None
    return None


def read_tree(src: Path, packages: dict[str, int]) -> Tree:
    """The :class:`Tree` of the packages ``packages`` under ``src``; an import of a package's
    module that does not exist is an ``AssertionError`` naming the file."""
    tree = Tree(src, _find_modules(src, packages))
    for module, (_, path) in tree.modules.items():
        syntax = ast.parse(path.read_text(), filename=str(path))
        tree.exports[module] = _exports(syntax)
        found = []
        raw = [*_raw_imports(syntax, module, path.name == "__init__.py"),
               *_imports_by_name(syntax, tree.modules)]
        for base, name, line in raw:
            if base.split(".")[0] not in packages:
                continue
            full = f"{base}.{name}" if name else base
            if full in tree.modules:  # ``from package import module`` imports the module
                found.append(Import(full, None, line))
                continue
            target = _resolve(base, tree.modules)
            assert target is not None, f"{path}:{line}: imports {full}, which is not in src/"
            found.append(Import(target, name if target == base else None, line))
        tree.imports[module] = found
    return tree


_TREE: Tree | None = None


def _src_tree() -> Tree:
    global _TREE
    if _TREE is None:
        _TREE = read_tree(SRC, LAYERS)
    return _TREE


# --- the rules, as functions of a tree ------------------------------------------------------

def package_problems(tree: Tree, layers: dict[str, int],
                     allowed_below: dict[str, set[str]]) -> list[str]:
    """Imports between packages against ``layers`` (and ``allowed_below``)."""
    problems = []
    for module, targets in tree.edges().items():
        package, path = tree.modules[module]
        for target in targets:
            other = tree.modules[target][0]
            if other == package:
                continue
            allowed = layers[other] < layers[package] and other in allowed_below.get(
                package, set(layers))
            if not allowed:
                problems.append(f"{path.relative_to(tree.src)}: {package} imports {target}")
    return sorted(problems)


def _pushbot_part(module: str) -> str | None:
    """The ``pushbot`` subpackage of ``module``, ``""`` for a top-level module, None outside."""
    parts = module.split(".")
    if parts[0] != "pushbot":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in PUSHBOT_LAYERS else ""


def pushbot_problems(edges: dict[str, set[str]]) -> list[str]:
    """Imports between ``pushbot`` subpackages against :data:`PUSHBOT_LAYERS`."""
    problems = []
    for module, targets in edges.items():
        part = _pushbot_part(module)
        if part is None:
            continue
        layer = PUSHBOT_LAYERS.get(part, TOP)
        for target in targets:
            other = _pushbot_part(target)
            if other is None or other == part:
                continue
            if PUSHBOT_LAYERS.get(other, TOP) >= layer:
                problems.append(f"{module} ({part or 'top'}) imports {target}")
    return sorted(problems)


def room(module: str) -> str:
    """The room of a module: its ``pushbot`` subpackage (``pushbot.runner``), else its
    package (``pushbot`` for the CLI's top-level modules)."""
    part = _pushbot_part(module)
    return f"pushbot.{part}" if part else module.split(".")[0]


def private_use_problems(tree: Tree) -> list[str]:
    """Imports across rooms of a name that is not public: a leading underscore anywhere in the
    imported name or module, or a name missing from the target's ``__all__``."""
    problems = []
    for module, found in tree.imports.items():
        for imp in found:
            if room(imp.target) == room(module):
                continue
            parts = imp.target.split(".") + ([imp.name] if imp.name else [])
            exported = tree.exports.get(imp.target)
            if any(p.startswith("_") and p != "__init__" for p in parts) or (
                    imp.name is not None and exported is not None and imp.name not in exported):
                what = f"{imp.target}.{imp.name}" if imp.name else imp.target
                problems.append(f"{module}:{imp.line} uses {what}, which "
                                f"{room(imp.target)} does not export")
    return sorted(problems)


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), and modules that
    import themselves."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in edges.get(v, ()):
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


# --- the checkers on hand-made graphs and trees ------------------------------------------------

def test_cycle_finder_by_hand() -> None:
    assert cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"d"}}) == [["a", "b", "c"],
                                                                        ["d"]]


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def test_every_kind_of_import_closes_a_cycle(tmp_path: Path) -> None:
    # lib.a -> lib.b at module level, lib.b -> lib.c inside a function, lib.c -> lib.a only
    # for annotations: one cycle of three; lib.d imports lib.a by name, lib.e nothing.
    _write(tmp_path, {
        "lib/lib/__init__.py": "",
        "lib/lib/a.py": "from lib.b import thing\n",
        "lib/lib/b.py": "def thing():\n    from . import c\n    return c\n",
        "lib/lib/c.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                         "    from lib.a import thing\n"),
        "lib/lib/d.py": "import importlib\nNAMES = {'x': 'lib.a'}\nimportlib.import_module('x')\n",
        "lib/lib/e.py": "import os\n",
    })
    tree = read_tree(tmp_path, {"lib": 0})
    assert tree.edges() == {"lib": set(), "lib.a": {"lib.b"}, "lib.b": {"lib.c"},
                            "lib.c": {"lib.a"}, "lib.d": {"lib.a"}, "lib.e": set()}
    assert cycles(tree.edges()) == [["lib.a", "lib.b", "lib.c"]]


def test_package_rule_on_a_hand_made_tree(tmp_path: Path) -> None:
    _write(tmp_path, {
        "low/low/__init__.py": "",
        "low/low/x.py": "def f():\n    import high.y\n",  # upward, lazily
        "high/high/__init__.py": "",
        "high/high/y.py": "from low import x\nfrom low.x import _private, f\n",
        "other/other/__init__.py": "import high\n",  # a sibling of the same layer
    })
    tree = read_tree(tmp_path, {"low": 0, "high": 1, "other": 1})
    assert package_problems(tree, {"low": 0, "high": 1, "other": 1}, {}) == [
        "low/low/x.py: low imports high.y", "other/other/__init__.py: other imports high"]
    assert private_use_problems(tree) == [
        "high.y:2 uses low.x._private, which low does not export"]


def test_public_names_follow_all(tmp_path: Path) -> None:
    _write(tmp_path, {
        "low/low/__init__.py": "",
        "low/low/x.py": "__all__ = ['f']\ndef f(): ...\ndef g(): ...\n",
        "high/high/__init__.py": "",
        "high/high/y.py": "from low.x import f, g\nimport low._hidden\n",
        "low/low/_hidden.py": "",
    })
    tree = read_tree(tmp_path, {"low": 0, "high": 1})
    assert private_use_problems(tree) == [
        "high.y:1 uses low.x.g, which low does not export",
        "high.y:2 uses low._hidden, which low does not export"]


def test_pushbot_layer_rule_by_hand() -> None:
    assert pushbot_problems({"pushbot.ros2cli.bag": {"pushbot.runner.graph_nodes"},
                             "pushbot.viz.view": {"pushbot.ros2cli.bag", "push_ros.dds"},
                             "pushbot.runner.demo": {"pushbot.experiments.inprocess"},
                             "pushbot.experiments.replay": {"pushbot.cli"},
                             "pushbot.cli": {"pushbot.runner.up"}}) == [
        "pushbot.experiments.replay (experiments) imports pushbot.cli",
        "pushbot.ros2cli.bag (ros2cli) imports pushbot.runner.graph_nodes",
        "pushbot.runner.demo (runner) imports pushbot.experiments.inprocess"]


# --- the rules on the source tree ----------------------------------------------------------

def test_packages_import_only_lower_layers() -> None:
    problems = package_problems(_src_tree(), LAYERS, ALLOWED_BELOW)
    assert not problems, "\n".join(problems)


def test_pushbot_subpackages_import_only_lower_ones() -> None:
    assert set(PUSHBOT_LAYERS) == {p.name for p in (SRC / "pushbot" / "pushbot").iterdir()
                                   if (p / "__init__.py").exists()}
    problems = pushbot_problems(_src_tree().edges())
    assert not problems, "\n".join(problems)


def test_rooms_use_each_other_only_through_public_names() -> None:
    problems = private_use_problems(_src_tree())
    assert not problems, "\n".join(problems)


def test_the_cli_command_table_counts_as_imports() -> None:
    # The by-name rule sees what ``pushbot.cli`` loads: its edges reach every command module.
    edges = _src_tree().edges()["pushbot.cli"]
    assert {"pushbot.runner.demo", "pushbot.experiments.evaluate", "pushbot.viz.view",
            "pushbot.ros2cli.bag"} <= edges


def test_package_xml_declares_first_party_dependencies() -> None:
    tree = _src_tree()
    used: dict[str, set[str]] = {p: set() for p in LAYERS}
    for module, targets in tree.edges().items():
        package = tree.modules[module][0]
        used[package] |= {tree.modules[t][0] for t in targets} - {package}
    problems = []
    for package, needed in used.items():
        xml = (SRC / package / "package.xml").read_text()
        declared = set(re.findall(r"<(?:exec_|build_)?depend>([\w]+)</", xml))
        problems += [f"{package}/package.xml does not declare {dep}"
                     for dep in sorted(needed - declared)]
    assert not problems, "\n".join(problems)


def test_no_import_cycles() -> None:
    # A package's __init__ importing its own submodules (re-exports) is not a cycle when the
    # submodule does not import the package back; such edges stay in the graph.
    found = cycles(_src_tree().edges())
    assert not found, "import cycles: " + "; ".join(" <-> ".join(c) for c in found)
