"""``pushbot param``: the project's replacement for ``ros2 param`` (list, get, set, dump).

Through the node's parameter services (rcl_interfaces ``ListParameters``, ``GetParameters``,
``SetParameters``, ``DescribeParameters``), waiting only for the ones a command calls:

- ``param list NODE``: the parameter names, one per line (indented, as ``ros2 param list``);
- ``param get NODE NAME``: what ``ros2 param get`` prints (``Double value is: 0.1``,
  ``Double values are: [0.0, 1.0]``, ``Parameter not set.``; ``--hide-type``: the value only);
  ``param list --param-type`` names the types as ``ros2 param`` does (``double array``);
- ``param set NODE NAME VALUE``: the value is read as YAML, as ``ros2 param set`` does
  (``3`` an integer, ``3.0`` a double, ``true`` a bool, ``[1.0, 2.0]`` a double array, anything
  else a string); an integer for a double parameter is sent as a double. The node may refuse
  (read-only, out of range, invalid configuration): its reason is printed and the status is 1;
- ``param dump NODE``: every parameter as a parameter file (``/node: ros__parameters: ...``,
  dotted names nested), usable as ``--params-file``.

Exit codes: 0 success, 1 when the node's parameter services did not answer within
``--timeout`` or the node refused, 2 for usage errors (unknown parameter, bad name).
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, Any

import yaml

from pushbot.ros2cli.discovery import (
    EXIT_USAGE,
    cli_node,
    full_node_name,
    run_graph_command,
    spin_until,
)
from pushbot.ros2cli.node import split_node_name

if TYPE_CHECKING:
    from rclpy.executors import Executor

DEFAULT_TIMEOUT = 10.0


class ParamError(RuntimeError):
    """A parameter request failed; ``status`` is the exit code."""

    def __init__(self, message: str, status: int = 1) -> None:
        super().__init__(message)
        self.status = status


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Sub-subcommands of ``pushbot param``."""
    sub = parser.add_subparsers(dest="param_command", metavar="{list,get,set,dump}")
    sub.required = True

    def common(p: argparse.ArgumentParser) -> None:
        p.add_argument("node", help="node name, e.g. /planner_node")
        p.add_argument("--timeout", type=float, default=DEFAULT_TIMEOUT,
                       help="seconds to wait for the node's parameter services and each "
                            "answer (default: %(default)s)")

    p = sub.add_parser("list", help="list a node's parameters",
                       description="List the parameter names of a node.")
    common(p)
    p.add_argument("--param-type", action="store_true", help="also print each type")
    p.set_defaults(param_handler=cmd_list)

    p = sub.add_parser("get", help="print a parameter value",
                       description="Print the value of one parameter of a node.")
    common(p)
    p.add_argument("name", help="parameter name, e.g. goal_tolerance.xy")
    p.add_argument("--hide-type", action="store_true", help="print the value only")
    p.set_defaults(param_handler=cmd_get)

    p = sub.add_parser("set", help="set a parameter value",
                       description="Set one parameter of a node; the value is read as YAML "
                                   "(3 integer, 3.0 double, true bool, [1.0, 2.0] double "
                                   "array, anything else a string).")
    common(p)
    p.add_argument("name", help="parameter name")
    p.add_argument("value", help="new value (YAML)")
    p.set_defaults(param_handler=cmd_set)

    p = sub.add_parser("dump", help="print all parameters as a parameter file",
                       description="Print every parameter of a node as a YAML parameter file "
                                   "(usable as --ros-args --params-file).")
    common(p)
    p.set_defaults(param_handler=cmd_dump)


def run_param(args: argparse.Namespace) -> int:
    """Handler of ``pushbot param``: dispatch to the sub-subcommand."""
    try:
        split_node_name(args.node)
    except ValueError as exc:
        print(f"pushbot param {args.param_command}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    try:
        return run_graph_command(args, args.param_handler, "param")
    except ParamError as exc:
        print(f"pushbot param {args.param_command}: {exc}", file=sys.stderr)
        return exc.status


class _Client:
    """Clients of ``node_name``'s parameter services, created and waited for (at most
    ``timeout``) only when a command needs them: waiting for all six parameter services, as
    ``AsyncParameterClient.wait_for_services`` does, costs seconds of discovery."""

    def __init__(self, node: Any, executor: Executor, node_name: str, timeout: float) -> None:
        base, namespace = split_node_name(node_name)
        self.name = full_node_name(base, namespace)
        self.node = node
        self.executor = executor
        self.timeout = max(timeout, 0.0)
        self.clients: dict[str, Any] = {}

    def call(self, service: str, request: Any) -> Any:
        """Call ``<node>/<service>`` with ``request``; its response or :class:`ParamError`."""
        client = self.clients.get(service)
        if client is None:
            client = self.node.create_client(_service_types()[service],
                                             f"{self.name}/{service}")
            self.clients[service] = client
        if not spin_until(self.executor, client.service_is_ready,
                          time.monotonic() + self.timeout):
            raise ParamError(f"node {self.name} has no parameter service {service} (waited "
                             f"{self.timeout:g} s): is it running?")
        future = client.call_async(request)
        if not spin_until(self.executor, future.done, time.monotonic() + self.timeout):
            raise ParamError(f"no answer from {self.name}/{service} within {self.timeout:g} s")
        if future.exception() is not None:
            raise ParamError(f"{self.name}/{service} failed: {future.exception()}")
        return future.result()

    def names(self) -> list[str]:
        from rcl_interfaces.srv import ListParameters

        return sorted(self.call("list_parameters", ListParameters.Request()).result.names)

    def describe(self, names: list[str]) -> list[Any]:
        from rcl_interfaces.srv import DescribeParameters

        return list(self.call("describe_parameters",
                              DescribeParameters.Request(names=names)).descriptors)

    def values(self, names: list[str]) -> list[Any]:
        from rcl_interfaces.srv import GetParameters

        return list(self.call("get_parameters", GetParameters.Request(names=names)).values)

    def set(self, parameters: list[Any]) -> Any:
        from rcl_interfaces.srv import SetParameters

        return self.call("set_parameters", SetParameters.Request(parameters=parameters))

    def require(self, name: str) -> Any:
        """The descriptor of ``name``; :class:`ParamError` (status 2) if it does not exist."""
        from rcl_interfaces.msg import ParameterType

        descriptor = self.describe([name])
        if not descriptor or descriptor[0].type == ParameterType.PARAMETER_NOT_SET:
            raise ParamError(f"node {self.name} has no parameter '{name}'", EXIT_USAGE)
        return descriptor[0]


def _service_types() -> dict[str, type]:
    from rcl_interfaces.srv import (
        DescribeParameters,
        GetParameters,
        ListParameters,
        SetParameters,
    )

    return {"list_parameters": ListParameters, "describe_parameters": DescribeParameters,
            "get_parameters": GetParameters, "set_parameters": SetParameters}


def type_name(parameter_type: int) -> str:
    """The parameter type as ``ros2 param`` names it (``double array``, ``integer``, ...)."""
    names = ("not set", "boolean", "integer", "double", "string", "byte array",
             "boolean array", "integer array", "double array", "string array")
    return names[parameter_type] if 0 <= parameter_type < len(names) else "unknown"


def value_line(value: Any, hide_type: bool = False) -> str:
    """What ``ros2 param get`` prints for a ``ParameterValue``: ``Double value is: 0.1``,
    ``Double values are: [0.0, 1.0]``, ``Parameter not set.``; only the value with
    ``hide_type``. Values print as Python prints them (``True``, ``['a', 'b']``)."""
    from rcl_interfaces.msg import ParameterType as T

    fields = {T.PARAMETER_BOOL: ("Boolean value is:", "bool_value"),
              T.PARAMETER_INTEGER: ("Integer value is:", "integer_value"),
              T.PARAMETER_DOUBLE: ("Double value is:", "double_value"),
              T.PARAMETER_STRING: ("String value is:", "string_value"),
              T.PARAMETER_BYTE_ARRAY: ("Byte values are:", "byte_array_value"),
              T.PARAMETER_BOOL_ARRAY: ("Boolean values are:", "bool_array_value"),
              T.PARAMETER_INTEGER_ARRAY: ("Integer values are:", "integer_array_value"),
              T.PARAMETER_DOUBLE_ARRAY: ("Double values are:", "double_array_value"),
              T.PARAMETER_STRING_ARRAY: ("String values are:", "string_array_value")}
    if value.type not in fields:
        return "None" if hide_type else "Parameter not set."
    label, field_name = fields[value.type]
    python = getattr(value, field_name)
    python = python.tolist() if hasattr(python, "tolist") else python
    python = list(python) if isinstance(python, tuple) else python
    return str(python) if hide_type else f"{label} {python}"


def cmd_list(args: argparse.Namespace) -> int:
    """``pushbot param list NODE [--param-type]``."""
    with cli_node("param_list") as (node, executor):
        client = _Client(node, executor, args.node, args.timeout)
        names = client.names()
        types = [d.type for d in client.describe(names)] if args.param_type and names else []
    for i, name in enumerate(names):
        print(f"  {name}" + (f" (type: {type_name(types[i])})" if types else ""))
    return 0


def cmd_get(args: argparse.Namespace) -> int:
    """``pushbot param get NODE NAME [--hide-type]``."""
    from rcl_interfaces.msg import ParameterValue

    with cli_node("param_get") as (node, executor):
        client = _Client(node, executor, args.node, args.timeout)
        client.require(args.name)
        values = client.values([args.name])
    # rclpy answers no value at all for a parameter declared without one.
    print(value_line(values[0] if values else ParameterValue(), args.hide_type))
    return 0


def parameter_value(text: str, declared_type: int) -> Any:
    """The ``ParameterValue`` for ``text`` read as YAML (rclpy's rule, as ``ros2 param set``),
    an integer (array) turned into a double (array) when the parameter is declared double."""
    from rcl_interfaces.msg import ParameterType
    from rclpy.parameter import get_parameter_value

    value = get_parameter_value(text)
    if declared_type == ParameterType.PARAMETER_DOUBLE \
            and value.type == ParameterType.PARAMETER_INTEGER:
        value.type, value.double_value = ParameterType.PARAMETER_DOUBLE, float(value.integer_value)
    elif declared_type == ParameterType.PARAMETER_DOUBLE_ARRAY \
            and value.type == ParameterType.PARAMETER_INTEGER_ARRAY:
        value.type = ParameterType.PARAMETER_DOUBLE_ARRAY
        value.double_array_value = [float(v) for v in value.integer_array_value]
    return value


def cmd_set(args: argparse.Namespace) -> int:
    """``pushbot param set NODE NAME VALUE``."""
    from rcl_interfaces.msg import Parameter

    with cli_node("param_set") as (node, executor):
        client = _Client(node, executor, args.node, args.timeout)
        descriptor = client.require(args.name)
        msg = Parameter(name=args.name, value=parameter_value(args.value, descriptor.type))
        response = client.set([msg])
    result = response.results[0] if response.results else None
    if result is None or not result.successful:
        reason = result.reason if result is not None else "no result"
        print(f"Setting parameter failed: {reason}", file=sys.stderr)
        return 1
    print("Set parameter successful")
    return 0


def nest(values: dict[str, Any]) -> dict[str, Any]:
    """Dotted parameter names as nested mappings (``a.b: 1`` -> ``a: {b: 1}``), as parameter
    files write them; names under a prefix that is itself a parameter stay dotted."""
    out: dict[str, Any] = {}
    for name in sorted(values):
        parts = name.split(".")
        if any(".".join(parts[:i]) in values for i in range(1, len(parts))) or any(
                other.startswith(name + ".") for other in values):
            out[name] = values[name]
            continue
        level = out
        for part in parts[:-1]:
            level = level.setdefault(part, {})
        level[parts[-1]] = values[name]
    return out


def cmd_dump(args: argparse.Namespace) -> int:
    """``pushbot param dump NODE``."""
    from rclpy.parameter import parameter_value_to_python

    with cli_node("param_dump") as (node, executor):
        client = _Client(node, executor, args.node, args.timeout)
        names = client.names()
        values = client.values(names) if names else []
        if len(values) != len(names):
            # rclpy answers an empty list when one of the names has no value (declared
            # without one): ask one by one and leave those out, as they cannot be loaded.
            values = [(client.values([name]) or [None])[0] for name in names]
        full = client.name
    data = {name: parameter_value_to_python(v) for name, v in zip(names, values, strict=True)
            if v is not None and v.type != 0}
    print(yaml.safe_dump({full: {"ros__parameters": nest(data)}}, default_flow_style=False,
                         sort_keys=True), end="")
    return 0
