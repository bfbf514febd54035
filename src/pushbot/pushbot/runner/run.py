"""``pushbot run``: start a node from the pip install the way ``ros2 run`` does.

Nodes are the ``console_scripts`` entry points of the node distributions (the same entry points
colcon installs as ``lib/<pkg>/<node>``), found with :mod:`importlib.metadata`, so there is no
second table of nodes to keep in sync. ``pushbot run <node> [args...]`` (or, as with ``ros2
run``, ``pushbot run <pkg> <node> [args...]``) replaces ``sys.argv`` with ``[<node>, args...]``
and calls the node's ``main()`` in this process; ``--ros-args ...`` therefore reaches
``rclpy.init()`` unchanged. A ``--params-file`` that does not exist is reported in one line
(exit status 2) before the node starts, instead of rcl's error and a traceback.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import sys
from dataclasses import dataclass

from pushbot.ros2cli.discovery import EXIT_USAGE

NODE_DISTRIBUTIONS = ("sim_bridge", "push_perception", "push_estimator", "push_planner",
                      "push_executor")
"""Distributions whose console scripts are ROS nodes."""


@dataclass(frozen=True)
class NodeEntry:
    """One runnable node: its executable name, its package and its ``module:function``."""

    name: str
    package: str
    target: str
    entry_point: importlib.metadata.EntryPoint


def discover_nodes() -> list[NodeEntry]:
    """All node executables of the installed node distributions, sorted by package and name."""
    nodes = []
    for dist_name in NODE_DISTRIBUTIONS:
        try:
            dist = importlib.metadata.distribution(dist_name)
        except importlib.metadata.PackageNotFoundError:
            continue
        for ep in dist.entry_points:
            if ep.group == "console_scripts":
                nodes.append(NodeEntry(ep.name, dist_name, ep.value, ep))
    return sorted(nodes, key=lambda n: (n.package, n.name))


def missing_distributions() -> list[str]:
    """Node distributions that are not installed (``make venv`` installs them all)."""
    missing = []
    for dist_name in NODE_DISTRIBUTIONS:
        try:
            importlib.metadata.distribution(dist_name)
        except importlib.metadata.PackageNotFoundError:
            missing.append(dist_name)
    return missing


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``pushbot run``."""
    parser.add_argument("--list", action="store_true", help="list the nodes and their packages")
    parser.add_argument(
        "node", nargs="?", help="node executable (optionally preceded by its package)"
    )
    parser.add_argument(
        "node_args",
        nargs=argparse.REMAINDER,
        help="passed to the node unchanged, e.g. --ros-args -p name:=value -r from:=to",
    )


def format_node_list(nodes: list[NodeEntry]) -> str:
    """``<package> <node>`` lines, as ``ros2 pkg executables`` prints them."""
    width = max((len(n.package) for n in nodes), default=0)
    return "\n".join(f"{n.package:<{width}}  {n.name}" for n in nodes)


def _known(nodes: list[NodeEntry]) -> str:
    return ", ".join(f"{n.name} ({n.package})" for n in nodes) or "none installed: run make venv"


def resolve_node(
    nodes: list[NodeEntry], words: list[str]
) -> tuple[NodeEntry | None, list[str], str]:
    """Pick the node named by ``words`` (``[node, args...]`` or ``[pkg, node, args...]``).

    Returns ``(node, remaining_args, error)``; ``node`` is ``None`` with a message on failure.
    """
    first, rest = words[0], words[1:]
    packages = {n.package for n in nodes}
    if first in packages and rest:
        match = [n for n in nodes if n.package == first and n.name == rest[0]]
        if match:
            return match[0], rest[1:], ""
    match = [n for n in nodes if n.name == first]
    if len(match) == 1:
        return match[0], rest, ""
    if len(match) > 1:
        owners = ", ".join(n.package for n in match)
        return None, rest, f"node '{first}' exists in several packages ({owners}): " \
            f"use pushbot run <pkg> {first}"
    if first in packages:
        in_pkg = ", ".join(n.name for n in nodes if n.package == first) or "none"
        return None, rest, f"package '{first}' has no node '{rest[0] if rest else ''}'; " \
            f"its nodes: {in_pkg}"
    return None, rest, f"unknown node '{first}'. Known nodes: {_known(nodes)}"


def missing_params_file(node_args: list[str]) -> str | None:
    """The first ``--params-file PATH`` after ``--ros-args`` whose file does not exist."""
    in_ros_args = False
    for i, word in enumerate(node_args):
        if word == "--ros-args":
            in_ros_args = True
        elif word == "--":
            in_ros_args = False
        elif in_ros_args and word == "--params-file" and i + 1 < len(node_args):
            if not os.path.isfile(node_args[i + 1]):
                return node_args[i + 1]
    return None


def run_node(args: argparse.Namespace) -> int:
    """Handler of ``pushbot run``; returns the node's exit status."""
    nodes = discover_nodes()
    missing = missing_distributions()
    if args.list:
        if nodes:
            print(format_node_list(nodes))
        if missing:
            print(f'pushbot run: not installed: {", ".join(missing)} (run make venv)',
                  file=sys.stderr)
        return 0 if nodes else 1
    if not args.node:
        print(f"pushbot run: name a node. Known nodes: {_known(nodes)}", file=sys.stderr)
        return EXIT_USAGE
    node, node_args, error = resolve_node(nodes, [args.node, *args.node_args])
    if node is None:
        print(f"pushbot run: {error}", file=sys.stderr)
        return EXIT_USAGE
    missing_file = missing_params_file(node_args)
    if missing_file is not None:
        print(f"pushbot run: --params-file {missing_file}: no such file", file=sys.stderr)
        return EXIT_USAGE
    try:
        main = node.entry_point.load()
    except ImportError as exc:
        print(f"pushbot run: cannot import {node.name} ({node.package}) from {node.target}: "
              f"{exc}", file=sys.stderr)
        return 1
    sys.argv = [node.name, *node_args]
    result = main()
    # Same convention as a console_scripts wrapper: sys.exit(main()).
    if result is None or isinstance(result, int):
        return result or 0
    print(result, file=sys.stderr)
    return 1
