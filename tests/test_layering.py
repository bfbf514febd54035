"""The layering of docs/ARCHITECTURE.md#packages, enforced over every first-party import.

Every ``import`` of the source tree counts, lazy ones inside functions included; only imports
under ``if TYPE_CHECKING:`` are left out (they never run). Checked:

- the direction ``push_core <- push_ros <- node packages <- pushbot``: a package imports only
  itself and packages of a lower layer; the node packages never import each other; the
  deployment package ``pushbot_bringup`` (launch file included) imports no ``pushbot`` module
  and no node package, only ``push_ros``;
- inside ``pushbot``, the direction between its subpackages (docs/ARCHITECTURE.md#packages):
  ``ros2cli <- viz <- runner <- experiments <- pushbot.cli``; the one exception is the trial
  definition ``pushbot.experiments.protocol`` (it imports no ``pushbot`` module), which the
  runner runs;
- every first-party package a package imports is declared in its ``package.xml``;
- no import cycle among first-party modules.
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
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
#: (subpackage, module) imports allowed against the layers: the runner runs the experiments'
#: trials, whose definition imports no pushbot module (test below).
PUSHBOT_EXCEPTIONS = {("runner", "pushbot.experiments.protocol")}


def _type_checking_lines(tree: ast.Module) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def _module_name(path: Path, package_dir: Path) -> str:
    rel = path.relative_to(package_dir).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, module: str) -> Iterator[str]:
    """Absolute names imported by ``path`` (module ``module``) at run time."""
    tree = ast.parse(path.read_text(), filename=str(path))
    skip = _type_checking_lines(tree)
    is_package = path.name == "__init__.py"
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = module.split(".")
                keep = len(parts) - node.level + (1 if is_package else 0)
                base = ".".join(parts[:keep] + ([base] if base else []))
            for alias in node.names:
                yield f"{base}.{alias.name}" if base else alias.name


def _first_party_modules() -> dict[str, tuple[str, Path]]:
    """module name -> (package, file) for every module under src/<package>/<package>/ and the
    bringup launch files (as ``pushbot_bringup.launch.<name>``)."""
    modules: dict[str, tuple[str, Path]] = {}
    for package in LAYERS:
        root = SRC / package
        for path in sorted((root / package).rglob("*.py")):
            modules[_module_name(path, root)] = (package, path)
    for path in sorted((SRC / "pushbot_bringup" / "launch").glob("*.py")):
        modules[f"pushbot_bringup.launch.{path.stem.replace('.', '_')}"] = ("pushbot_bringup",
                                                                          path)
    return modules


def _resolve(name: str, modules: dict[str, tuple[str, Path]]) -> str | None:
    """The first-party module ``name`` refers to (``a.b.c`` may be ``a.b`` + attribute c)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _edges() -> dict[str, set[str]]:
    modules = _first_party_modules()
    edges: dict[str, set[str]] = {m: set() for m in modules}
    for module, (_, path) in modules.items():
        for name in _imports(path, module):
            if name.split(".")[0] not in LAYERS:
                continue
            target = _resolve(name, modules)
            assert target is not None, f"{path}: imports {name}, which is not in src/"
            if target != module:
                edges[module].add(target)
    return edges


def test_packages_import_only_lower_layers() -> None:
    modules = _first_party_modules()
    problems = []
    for module, targets in _edges().items():
        package, path = modules[module]
        for target in targets:
            other = modules[target][0]
            if other == package:
                continue
            allowed = LAYERS[other] < LAYERS[package] and other in ALLOWED_BELOW.get(
                package, set(LAYERS))
            if not allowed:
                problems.append(f"{path.relative_to(SRC)}: {package} imports {target}")
    assert not problems, "\n".join(sorted(problems))


def _pushbot_part(module: str) -> str | None:
    """The ``pushbot`` subpackage of ``module``, ``""`` for a top-level module, None outside."""
    parts = module.split(".")
    if parts[0] != "pushbot":
        return None
    return parts[1] if len(parts) > 1 and parts[1] in PUSHBOT_LAYERS else ""


def _pushbot_problems(edges: dict[str, set[str]]) -> list[str]:
    """Imports between ``pushbot`` subpackages against :data:`PUSHBOT_LAYERS`."""
    problems = []
    for module, targets in edges.items():
        part = _pushbot_part(module)
        if part is None:
            continue
        layer = PUSHBOT_LAYERS.get(part, TOP)
        for target in targets:
            other = _pushbot_part(target)
            if other is None or other == part or (part, target) in PUSHBOT_EXCEPTIONS:
                continue
            if PUSHBOT_LAYERS.get(other, TOP) >= layer:
                problems.append(f"{module} ({part or 'top'}) imports {target}")
    return sorted(problems)


def test_pushbot_layer_rule_by_hand() -> None:
    assert _pushbot_problems({"pushbot.ros2cli.bag": {"pushbot.runner.graph_nodes"},
                              "pushbot.viz.view": {"pushbot.ros2cli.bag", "push_ros.dds"},
                              "pushbot.runner.demo": {"pushbot.experiments.protocol"},
                              "pushbot.runner.up": {"pushbot.experiments.evaluate"},
                              "pushbot.experiments.replay": {"pushbot.cli"},
                              "pushbot.cli": {"pushbot.runner.up"}}) == [
        "pushbot.experiments.replay (experiments) imports pushbot.cli",
        "pushbot.ros2cli.bag (ros2cli) imports pushbot.runner.graph_nodes",
        "pushbot.runner.up (runner) imports pushbot.experiments.evaluate"]


def test_pushbot_subpackages_import_only_lower_ones() -> None:
    assert set(PUSHBOT_LAYERS) == {p.name for p in (SRC / "pushbot" / "pushbot").iterdir()
                                   if (p / "__init__.py").exists()}
    problems = _pushbot_problems(_edges())
    assert not problems, "\n".join(problems)


def test_the_pushbot_exceptions_import_no_pushbot_module() -> None:
    edges = _edges()
    for _, module in PUSHBOT_EXCEPTIONS:
        assert not {t for t in edges[module] if _pushbot_part(t) is not None}, module


def test_package_xml_declares_first_party_dependencies() -> None:
    modules = _first_party_modules()
    used: dict[str, set[str]] = {p: set() for p in LAYERS}
    for module, targets in _edges().items():
        package = modules[module][0]
        used[package] |= {modules[t][0] for t in targets} - {package}
    problems = []
    for package, needed in used.items():
        xml = (SRC / package / "package.xml").read_text()
        declared = set(re.findall(r"<(?:exec_|build_)?depend>([\w]+)</", xml))
        problems += [f"{package}/package.xml does not declare {dep}"
                     for dep in sorted(needed - declared)]
    assert not problems, "\n".join(problems)


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
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
        for w in sorted(edges[v]):
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
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return found


def test_cycle_finder_by_hand() -> None:
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_no_import_cycles() -> None:
    # A package's __init__ importing its own submodules (re-exports) is not a cycle when the
    # submodule does not import the package back; such edges stay in the graph.
    cycles = _cycles(_edges())
    assert not cycles, "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles)
