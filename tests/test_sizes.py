"""Size limits of issue 21: node files thin, no folder too big to find one's way in.

Code lines are counted without docstrings, comments and blank lines: every line that holds a
token of a statement or expression and is not part of a module, class or function docstring.
"""

from __future__ import annotations

import ast
import io
import tokenize
from collections import defaultdict
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"
#: code lines a ``*_node.py`` file may hold (parameters, endpoints, conversion, wiring)
MAX_NODE_LINES = 300
#: code lines of the modules directly in one folder
MAX_FOLDER_LINES = 4000
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


def _modules() -> list[Path]:
    return [p for p in SRC.rglob("*.py") if "build" not in p.parts]


def test_node_files_are_thin() -> None:
    nodes = {str(p.relative_to(SRC)): code_lines(p.read_text()) for p in _modules()
             if p.name.endswith("_node.py")}
    assert len(nodes) >= 5
    assert {name: n for name, n in nodes.items() if n > MAX_NODE_LINES} == {}


def test_no_folder_over_the_limit() -> None:
    folders: dict[str, int] = defaultdict(int)
    for path in _modules():
        folders[str(path.parent.relative_to(SRC))] += code_lines(path.read_text())
    assert {name: n for name, n in folders.items() if n > MAX_FOLDER_LINES} == {}
