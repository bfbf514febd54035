"""Interface documents generated from the nodes' parameter tables (one place per fact).

Every node declares its parameters once, as a :class:`~push_ros.node.ParamSpec` table
(``PARAMETERS`` of its configuration module). Two kinds of files restate that table and are
generated from it here, so that they cannot drift; ``tests/test_interfaces.py`` checks that
every one of them is current:

- Markdown (``docs/INTERFACES.md``): every region between
  ``<!-- BEGIN parameters <node> <module> -->`` and ``<!-- END parameters <node> -->`` is the
  table of ``<module>.PARAMETERS`` (name, type, default, description with range and
  read-only).
- Parameter files (``src/pushbot_bringup/config/*.yaml``): a file whose first line is
  ``# Generated from <module> by ...`` is :func:`push_ros.node.parameter_yaml` of that module's
  ``NODE_NAME``, ``YAML_HEADER``, optional ``YAML_EXTRA`` (parameters ROS declares itself,
  e.g. ``use_sim_time``, written first) and optional ``YAML_NOTES`` (comment paragraphs before
  a parameter).

The documents name the modules they are generated from; this module names no node package, so
``push_ros`` stays below the node packages (docs/ARCHITECTURE.md#packages). Regenerate after
changing a table::

    .venv/bin/python -m push_ros.interfaces docs/INTERFACES.md src/pushbot_bringup/config/*.yaml

(``--check``: change nothing, exit 1 naming the stale files).
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from rcl_interfaces.msg import ParameterType

from push_ros.node import ParamSpec, parameter_yaml, spec_note

__all__ = ["SIM_TIME", "YAML_FILES", "generated", "markdown_regions", "parameter_markdown",
           "regenerate_markdown", "regenerate_yaml", "type_name", "yaml_source"]

_REGION = re.compile(r"<!-- BEGIN parameters (?P<node>\S+) (?P<module>\S+) -->\n"
                     r"(?P<body>.*?)<!-- END parameters (?P=node) -->", re.DOTALL)
#: ``use_sim_time`` as the parameter files of the nodes that run on the simulator's clock write
#: it (``YAML_EXTRA``; ROS declares it, so it is in no node's table).
SIM_TIME = ParamSpec("use_sim_time", True, "Take time from /clock, published by sim_bridge. The "
                     "node's default is false (a real robot); this file's true is for running it "
                     "with the simulator (--params-file); pushbot.launch.py sets it from "
                     "sim:=true|false after this file, so it wins there.")
#: The bundled parameter files (relative to the repository root).
YAML_FILES = "src/pushbot_bringup/config/*.yaml"
_YAML_FIRST = re.compile(r"# Generated from (?P<module>[\w.]+) by ")
_ARRAY_TYPES = {ParameterType.PARAMETER_DOUBLE_ARRAY: "double[]",
                ParameterType.PARAMETER_INTEGER_ARRAY: "integer[]",
                ParameterType.PARAMETER_STRING_ARRAY: "string[]",
                ParameterType.PARAMETER_BOOL_ARRAY: "bool[]"}


def type_name(spec: ParamSpec) -> str:
    """The ROS parameter type of ``spec``: bool, integer, double, string or ``<type>[]``.

    Raises
    ------
    ValueError
        A default of another type, or an empty list default (its element type is unknown).
    """
    value = spec.default
    if value is None:
        return _ARRAY_TYPES.get(spec.type if spec.type is not None
                                else ParameterType.PARAMETER_DOUBLE_ARRAY, "unknown")
    if isinstance(value, list | tuple):
        if not value:
            raise ValueError(f"parameter {spec.name!r}: an empty list default has no type")
        return _scalar_type(spec.name, value[0]) + "[]"
    return _scalar_type(spec.name, value)


def _scalar_type(name: str, value: Any) -> str:
    for kind, label in ((bool, "bool"), (int, "integer"), (float, "double"), (str, "string")):
        if isinstance(value, kind):
            return label
    raise ValueError(f"parameter {name!r}: default {value!r} is not a ROS parameter type")


def _default_text(value: Any) -> str:
    if value is None:
        return "(unset)"
    if isinstance(value, bool):
        return "`true`" if value else "`false`"
    if isinstance(value, float):  # 6 significant digits, a double keeps its decimal point
        text = f"{value:.6g}"
        return f"`{text}`" if any(c in text for c in ".ein") else f"`{text}.0`"
    if isinstance(value, list | tuple):
        return "`[" + ", ".join(_default_text(v).strip("`") for v in value) + "]`"
    if isinstance(value, str):
        return f'`"{value}"`' if value else '`""`'
    return f"`{value}`"


def parameter_markdown(specs: Sequence[ParamSpec]) -> str:
    """A Markdown table of a parameter table: name, type, default, description.

    Parameters
    ----------
    specs : sequence of ParamSpec
        In declaration order.

    Returns
    -------
    str
        Header, separator and one row per parameter; the description gains the range
        as in the parameter files (:func:`push_ros.node.spec_note`); ``|`` is escaped.
    """
    rows = ["| parameter | type | default | description |", "| --- | --- | --- | --- |"]
    for spec in specs:
        cells = (f"`{spec.name}`", type_name(spec), _default_text(spec.default),
                 spec_note(spec))
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows) + "\n"


def _table_module(name: str) -> ModuleType:
    module = importlib.import_module(name)
    if not isinstance(getattr(module, "PARAMETERS", None), tuple):
        raise ValueError(f"module {name} has no PARAMETERS table")
    return module


def markdown_regions(text: str) -> list[tuple[str, str]]:
    """(node name, table module) of every generated parameter region of a Markdown text."""
    return [(m["node"], m["module"]) for m in _REGION.finditer(text)]


def regenerate_markdown(text: str) -> str:
    """``text`` with every parameter region (module docstring) replaced by its table."""
    def body(match: re.Match[str]) -> str:
        table = parameter_markdown(_table_module(match["module"]).PARAMETERS)
        return (f"<!-- BEGIN parameters {match['node']} {match['module']} -->\n{table}"
                f"<!-- END parameters {match['node']} -->")

    return _REGION.sub(body, text)


def yaml_source(text: str) -> str | None:
    """The table module a parameter file says it is generated from (its first line), or None."""
    match = _YAML_FIRST.match(text)
    return match["module"] if match else None


def regenerate_yaml(module_name: str) -> str:
    """The parameter file of the node whose table is ``module_name`` (module docstring).

    Parameters
    ----------
    module_name : str
        A module with ``PARAMETERS``, ``NODE_NAME`` and ``YAML_HEADER``.
    """
    module = _table_module(module_name)
    first = (f"Generated from {module_name} by .venv/bin/python -m push_ros.interfaces "
             f"{YAML_FILES}\n(edit the table and the YAML_* texts there, not this file).")
    specs = (*getattr(module, "YAML_EXTRA", ()), *module.PARAMETERS)
    return parameter_yaml(module.NODE_NAME, specs, first + "\n" + module.YAML_HEADER.strip(),
                          notes=getattr(module, "YAML_NOTES", None))


def generated(path: Path) -> str:
    """What the generated file ``path`` should hold (Markdown regions or a parameter file).

    Raises
    ------
    ValueError
        A ``.yaml`` file without the ``# Generated from <module> by`` first line, or another
        suffix than ``.md`` / ``.yaml``.
    """
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".md":
        return regenerate_markdown(text)
    if path.suffix == ".yaml":
        module = yaml_source(text)
        if module is None:
            raise ValueError(f"{path}: first line is not '# Generated from <module> by ...'")
        return regenerate_yaml(module)
    raise ValueError(f"{path}: not a .md or .yaml file")


def main(argv: Sequence[str] | None = None) -> int:
    """Regenerate (or ``--check``) the named files; 0, or 1 when one is stale under --check."""
    parser = argparse.ArgumentParser(prog="python -m push_ros.interfaces",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", type=Path)
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 if stale")
    args = parser.parse_args(argv)
    stale = []
    for path in args.files:
        text = generated(path)
        if text != path.read_text(encoding="utf-8"):
            stale.append(str(path))
            if not args.check:
                path.write_text(text, encoding="utf-8")
    if stale:
        print(("stale: " if args.check else "regenerated: ") + ", ".join(stale))
    return 1 if stale and args.check else 0


if __name__ == "__main__":
    sys.exit(main())
