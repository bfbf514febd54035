"""Sizes and shapes a reader can find their way in: modules, folders and the thin nodes.

- **Modules**: no source module over :data:`MAX_MODULE_LINES` plain lines (every line of the
  file counts, docstrings and comments too: that is what a reader scrolls through). A module
  that grows past it holds several jobs; split it by them. Only generated code is exempt (a
  file that says so with :data:`GENERATED_MARKER` in its first lines; none today).
- **Folders**: the modules directly in one folder hold at most :data:`MAX_FOLDER_LINES` code
  lines (docstrings, comments and blank lines left out).
- **Nodes**: a ``*_node.py`` module is the ROS wrapper of a core: parameters, endpoints,
  message conversion and wiring. Its shape says so, not a line count squeezed to a number:

  * it defines exactly one class, a subclass of ``rclpy.node.Node``, and a ``main()`` that
    starts it through the one entry-point helper ``push_ros.node.run_node``; any other
    module-level function is a private helper (a leading underscore);
  * importing it loads no numerical science library (:data:`SCIENCE_LIBRARIES`: torch, scipy,
    pybullet, ...; no module-level import of one): the science lives in a ROS-free core the
    node calls, tested without rclpy. A method may still import one to configure the process
    (the segmentation node sets torch's thread count);
  * it holds at most :data:`MAX_NODE_LINES` code lines: a node with a dozen endpoints needs
    about 300 written out readably (one statement per line, helpers where they belong); half
    as much again leaves room for a new endpoint, and beyond that logic has moved into the
    wrapper that belongs in the core.
"""

from __future__ import annotations

import ast
import io
import tokenize
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
#: plain lines a source module may hold
MAX_MODULE_LINES = 600
#: a generated module says so in one of its first five lines
GENERATED_MARKER = "@generated"
#: code lines of the modules directly in one folder
MAX_FOLDER_LINES = 4000
#: code lines a ``*_node.py`` file may hold (see the module docstring for the reason)
MAX_NODE_LINES = 450
#: libraries a node module must not import itself (its core does)
SCIENCE_LIBRARIES = frozenset({"torch", "scipy", "pybullet", "pybullet_utils", "pinocchio",
                               "shapely", "sklearn", "matplotlib"})
_LAYOUT = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
           tokenize.ENDMARKER}


def code_lines(source: str) -> int:
    """Lines of ``source`` holding code, docstrings, comments and blank lines left out."""
    docstrings: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                docstrings.update(range(first.lineno, (first.end_lineno or first.lineno) + 1))
    lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in _LAYOUT:
            lines.update(n for n in range(tok.start[0], tok.end[0] + 1) if n not in docstrings)
    return len(lines)


def _module_level(node: ast.AST) -> Iterator[ast.AST]:
    """The statements that run when the module is imported (not inside a def or class)."""
    for child in ast.iter_child_nodes(node):
        yield child
        if not isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            yield from _module_level(child)


def node_shape_problems(source: str) -> list[str]:
    """How the node module ``source`` departs from the thin shape (module docstring)."""
    tree = ast.parse(source)
    problems = []
    classes = [n for n in tree.body if isinstance(n, ast.ClassDef)]
    nodes = [c for c in classes
             if any(getattr(b, "id", getattr(b, "attr", None)) == "Node" for b in c.bases)]
    if len(classes) != 1 or len(nodes) != 1:
        problems.append(f"defines {len(classes)} classes, {len(nodes)} of them Node "
                        "subclasses (expected exactly one class, a Node)")
    functions = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    main = functions.pop("main", None)
    if main is None:
        problems.append("defines no main()")
    elif not any(isinstance(n, ast.Call) and getattr(n.func, "id", None) == "run_node"
                 for n in ast.walk(main)):
        problems.append("main() does not start the node through push_ros.node.run_node")
    problems += [f"public module-level function {name}()" for name in functions
                 if not name.startswith("_")]
    for node in _module_level(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        problems += [f"imports {name}" for name in names
                     if name.split(".")[0] in SCIENCE_LIBRARIES]
    lines = code_lines(source)
    if lines > MAX_NODE_LINES:
        problems.append(f"{lines} code lines (at most {MAX_NODE_LINES})")
    return problems


def test_code_lines_by_hand() -> None:
    source = '''"""Module
docstring."""
# a comment

def f(x):
    """Doc."""
    return (x +
            1)  # trailing comment
'''
    assert code_lines(source) == 3


def test_node_shape_rule_by_hand() -> None:
    thin = """
from rclpy.node import Node
from push_ros.node import run_node

def _helper(x):
    import torch  # configuring the process inside a function is allowed

    return x

class ThinNode(Node):
    pass

def main(args=None):
    run_node(ThinNode, "thin", args)
"""
    assert node_shape_problems(thin) == []
    crammed = """
import torch
from scipy.optimize import least_squares
from rclpy import node

class A(node.Node):
    pass

class Model:
    pass

def fit(x):
    return x

def main():
    rclpy.spin(A())
"""
    assert node_shape_problems(crammed) == [
        "defines 2 classes, 1 of them Node subclasses (expected exactly one class, a Node)",
        "main() does not start the node through push_ros.node.run_node",
        "public module-level function fit()",
        "imports torch",
        "imports scipy.optimize"]
    long = thin + "".join(f"X{i} = {i}\n" for i in range(MAX_NODE_LINES))
    assert node_shape_problems(long) == [f"{code_lines(long)} code lines (at most "
                                         f"{MAX_NODE_LINES})"]


def _modules() -> list[Path]:
    return [p for p in SRC.rglob("*.py") if "build" not in p.parts]


def _generated(path: Path) -> bool:
    with path.open(encoding="utf-8") as f:
        return any(GENERATED_MARKER in f.readline() for _ in range(5))


def test_no_module_over_the_limit() -> None:
    sizes = {str(p.relative_to(SRC)): len(p.read_text(encoding="utf-8").splitlines())
             for p in _modules() if not _generated(p)}
    assert len(sizes) > 100
    assert {name: n for name, n in sorted(sizes.items()) if n > MAX_MODULE_LINES} == {}


def test_nodes_have_the_thin_shape() -> None:
    nodes = {str(p.relative_to(SRC)): node_shape_problems(p.read_text(encoding="utf-8"))
             for p in _modules() if p.name.endswith("_node.py")}
    assert len(nodes) >= 5
    assert {name: found for name, found in nodes.items() if found} == {}


def test_no_folder_over_the_limit() -> None:
    folders: dict[str, int] = defaultdict(int)
    for path in _modules():
        folders[str(path.parent.relative_to(SRC))] += code_lines(path.read_text())
    assert {name: n for name, n in folders.items() if n > MAX_FOLDER_LINES} == {}
