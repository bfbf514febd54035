"""``pushbot node``: the project's replacement for ``ros2 node`` (list, info).

``node list`` prints the fully qualified names of the nodes in the graph (hidden nodes, whose
name starts with an underscore, such as the CLI's own, only with ``--all``); ``node info NODE``
prints its subscribers, publishers, service servers and service clients with their types, as
``ros2 node info`` does. Both wait until the graph has not changed for 2 s, after at least
3 s (at most ``--spin-time``; ``pushbot.ros2cli.discovery.wait_for_stable_graph``, the rule of every
graph command).

Exit codes: 0 success, 1 when the node is not in the graph, 2 for usage errors.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from pushbot.ros2cli.discovery import (
    DEFAULT_SPIN_TIME,
    EXIT_USAGE,
    add_spin_time,
    cli_node,
    full_node_name,
    run_graph_command,
    wait_for_graph,
    wait_for_stable_graph,
)

if TYPE_CHECKING:
    from rclpy.node import Node



def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-subcommands of ``pushbot node``."""
    sub = parser.add_subparsers(dest="node_command", metavar="{list,info}")
    sub.required = True
    p = sub.add_parser("list", help="list the nodes in the graph",
                       description="List the fully qualified names of the nodes in the graph "
                                   "once discovery has settled (at least 3 s, then nothing "
                                   "new for 2 s).")
    p.add_argument("-a", "--all", action="store_true",
                   help="also hidden nodes (names starting with _), e.g. the CLI's own")
    p.add_argument("-c", "--count-nodes", action="store_true",
                   help="only print the number of nodes")
    add_spin_time(p)
    p.set_defaults(node_handler=cmd_list)

    p = sub.add_parser("info", help="subscribers, publishers and services of a node",
                       description="Print the subscribers, publishers, service servers and "
                                   "service clients of a node with their types.")
    p.add_argument("node", help="node name, e.g. /planner_node (a leading / may be left out)")
    p.add_argument("--spin-time", type=float, default=DEFAULT_SPIN_TIME,
                   help="longest wait for the node and its endpoints in seconds "
                        "(default: %(default)s)")
    p.set_defaults(node_handler=cmd_info)


def run_rosnode(args: argparse.Namespace) -> int:
    """Handler of ``pushbot node``: dispatch to the sub-subcommand."""
    return run_graph_command(args, args.node_handler, "node")


def _hidden(name: str) -> bool:
    return any(part.startswith("_") for part in name.split("/") if part)


def cmd_list(args: argparse.Namespace) -> int:
    """``pushbot node list [-a] [-c]``."""
    with cli_node("node_list") as (node, executor):
        names, _, _ = wait_for_graph(node, executor, args.spin_time)
    shown = [n for n in names if args.all or not _hidden(n)]
    if args.count_nodes:
        print(len(shown))
    else:
        for name in shown:
            print(name)
    return 0


def split_node_name(name: str) -> tuple[str, str]:
    """``'/ns/name'`` (or ``'name'``) -> ``('name', '/ns')``.

    Raises
    ------
    ValueError
        An empty name or one ending in ``/``.
    """
    full = name if name.startswith("/") else f"/{name}"
    namespace, _, base = full.rpartition("/")
    if not base:
        raise ValueError(f"invalid node name '{name}'")
    return base, namespace or "/"


def _endpoints(node: Node, name: str, namespace: str) -> tuple[list[tuple[str, list[str]]], ...]:
    """Subscribers, publishers, service servers and clients of a node (sorted)."""
    return tuple(sorted((topic, list(types)) for topic, types in query(name, namespace))
                 for query in (node.get_subscriber_names_and_types_by_node,
                               node.get_publisher_names_and_types_by_node,
                               node.get_service_names_and_types_by_node,
                               node.get_client_names_and_types_by_node))


def cmd_info(args: argparse.Namespace) -> int:
    """``pushbot node info NODE``."""
    try:
        base, namespace = split_node_name(args.node)
    except ValueError as exc:
        print(f"pushbot node info: {exc}", file=sys.stderr)
        return EXIT_USAGE
    full = full_node_name(base, namespace)
    with cli_node("node_info") as (node, executor):
        deadline = time.monotonic() + max(args.spin_time, 0.0)
        (names,) = wait_for_stable_graph(
            executor, lambda: wait_view(node), deadline, ready=lambda snap: full in snap[0])
        if full not in names:
            print(f'pushbot node info: node {full} is not in the graph (waited '
                  f'{args.spin_time:g} s); running nodes: '
                  f'{", ".join(n for n in names if not _hidden(n)) or "none"}', file=sys.stderr)
            return 1

        def endpoints() -> tuple[list[tuple[str, list[str]]], ...]:
            try:
                return _endpoints(node, base, namespace)
            except Exception:  # rclpy raises NodeNameNonExistentError while it is half-known
                return ()

        sections = wait_for_stable_graph(executor, endpoints, deadline,
                                         ready=lambda snap: bool(snap))
    print(full)
    for title, items in zip(("Subscribers", "Publishers", "Service Servers", "Service Clients"),
                            sections or ((),) * 4, strict=True):
        print(f"  {title}:")
        for topic, types in items:
            print(f'    {topic}: {", ".join(types)}')
    return 0


def wait_view(node: Node) -> tuple[tuple[str, ...]]:
    """The node names only (what ``node info`` waits for first)."""
    return (tuple(full_node_name(n, ns) for n, ns in node.get_node_names_and_namespaces()),)
