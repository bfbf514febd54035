"""``pushbot service``: the project's replacement for ``ros2 service`` (list, call).

``service list [-t]`` prints the services of the graph once discovery has settled (nothing new
for 2 s after at least 3 s, ``pushbot.ros2cli.discovery.wait_for_stable_graph``); ``service call
SERVICE TYPE [YAML]`` builds the request from YAML as ``ros2 service call`` does
(``pushbot.ros2cli.messages``, the CLI's one message codec; type as ``pkg/srv/Type`` or
``pkg/Type``), waits for the server (at most ``--timeout``), calls it once and prints what
``ros2 service call`` prints: the request and the response objects' repr, e.g.::

    $ pushbot service call /sim_bridge_node/reset std_srvs/srv/Trigger
    requester: making request: std_srvs.srv.Trigger_Request()

    response:
    std_srvs.srv.Trigger_Response(success=True, message='scene reset: rect1 ...')

``--yaml`` prints the response as YAML instead (for scripts; ``yaml.safe_load`` reads it).

Exit codes: 0 when the response arrived, 1 when the service did not appear or answer within
``--timeout``, 2 for usage errors (unknown type, fields or values that do not fit the request).
"""

from __future__ import annotations

import argparse
import sys
import time

from pushbot.ros2cli.discovery import (
    EXIT_USAGE,
    add_spin_time,
    cli_node,
    import_message_class,
    run_graph_command,
    spin_until,
    wait_for_graph,
)
from pushbot.ros2cli.messages import (
    MessageFieldError,
    message_from_yaml,
    message_to_dict,
    to_yaml,
    zero_time,
)

DEFAULT_TIMEOUT = 10.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-subcommands of ``pushbot service``."""
    sub = parser.add_subparsers(dest="service_command", metavar="{list,call}")
    sub.required = True
    p = sub.add_parser("list", help="list the services in the graph",
                       description="List the services of the graph once discovery has "
                                   "settled (at least 3 s, then nothing new for 2 s).")
    p.add_argument("-t", "--show-types", action="store_true", help="also print the types")
    add_spin_time(p)
    p.set_defaults(service_handler=cmd_list)

    p = sub.add_parser(
        "call", help="call a service with a request given as YAML",
        description="Call a service once and print the response as YAML, like ros2 service "
                    "call: the type as pkg/srv/Type or pkg/Type, the request as a YAML "
                    "mapping (fields left out keep their defaults).")
    p.add_argument("service", help="service name, e.g. /sim_bridge_node/reset")
    p.add_argument("type", help="service type, e.g. std_srvs/srv/Trigger")
    p.add_argument("values", nargs="?", default="",
                   help="YAML mapping of the request fields (default: the default request)")
    p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT,
                   help="seconds to wait for the server and, then, for its response "
                        "(default: %(default)s)")
    p.add_argument("--yaml", action="store_true",
                   help="print the response as YAML (default: its repr, as `ros2 service call`)")
    p.set_defaults(service_handler=cmd_call)


def run_service(args: argparse.Namespace) -> int:
    """Handler of ``pushbot service``: dispatch to the sub-subcommand."""
    return run_graph_command(args, args.service_handler, "service")


def cmd_list(args: argparse.Namespace) -> int:
    """``pushbot service list [-t]``."""
    with cli_node("service_list") as (node, executor):
        _, _, services = wait_for_graph(node, executor, args.spin_time)
    for name, types in services:
        print(f'{name} [{", ".join(types)}]' if args.show_types else name)
    return 0


def import_service_class(type_string: str) -> type:
    """The class of ``'pkg/srv/Type'`` (``'pkg/Type'`` means ``pkg/srv/Type``).

    Raises
    ------
    LookupError
        Malformed, not installed, or not a service type.
    """
    parts = type_string.split("/")
    if len(parts) == 2:
        parts.insert(1, "srv")
    cls = import_message_class("/".join(parts))
    if not hasattr(cls, "Request") or not hasattr(cls, "Response"):
        raise LookupError(f"'{type_string}' is not a service type")
    return cls


def cmd_call(args: argparse.Namespace) -> int:
    """``pushbot service call SERVICE TYPE [VALUES] [--timeout S]``."""
    try:
        service_class = import_service_class(args.type)
        message_from_yaml(service_class.Request, args.values, now=zero_time)
    except (LookupError, MessageFieldError) as exc:
        print(f"pushbot service call: {exc}", file=sys.stderr)
        return EXIT_USAGE
    with cli_node("service_call") as (node, executor):
        try:
            client = node.create_client(service_class, args.service)
        except Exception as exc:  # rclpy's InvalidServiceNameException and kin
            print(f"pushbot service call: {str(exc).splitlines()[0]}", file=sys.stderr)
            return EXIT_USAGE
        name = client.srv_name
        request = message_from_yaml(service_class.Request, args.values,
                                    now=lambda: node.get_clock().now().to_msg())
        if not spin_until(executor, client.service_is_ready,
                          time.monotonic() + max(args.timeout, 0.0)):
            print(f"pushbot service call: service {name} is not available (waited "
                  f"{args.timeout:g} s)", file=sys.stderr)
            return 1
        print(f"requester: making request: {request!r}\n", flush=True)
        future = client.call_async(request)
        if not spin_until(executor, future.done, time.monotonic() + max(args.timeout, 0.0)):
            print(f"pushbot service call: no response from {name} within {args.timeout:g} s",
                  file=sys.stderr)
            return 1
        if future.exception() is not None:
            print(f"pushbot service call: {name} failed: {future.exception()}", file=sys.stderr)
            return 1
        response = future.result()
    if args.yaml:
        print("response:")
        print(to_yaml(message_to_dict(response), indent=2))
    else:
        print(f"response:\n{response!r}\n")
    return 0
