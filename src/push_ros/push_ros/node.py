"""Node helpers: the parameter table, the one ``main()`` runner and throttled logging.

Parameters. A node declares its parameters once, as a tuple of :class:`ParamSpec` (name,
default, description, bounds, read-only flag, constraints). :func:`declare_config` declares
them with :class:`~rcl_interfaces.msg.ParameterDescriptor` s (description, integer / floating
point range, read-only), reads them into the node's typed frozen config with its ``build``
function (which raises ``ValueError`` naming the parameter) and installs an on-set callback
that runs the same ``build`` over the current values with the new ones applied: a set that
would make the configuration invalid is rejected with the reason
(``SetParametersResult.reason``) and changes nothing. When a valid new value takes effect is
the node's business (the episode parameters on ``~/reset``).

Running. :func:`run_node` is the Jazzy ``main()`` shape, once for every node: the project's DDS
rule (:func:`push_ros.dds.apply_default_profile`, so a node started by its console script or
``ros2 run`` gets the same transports as through ``pushbot`` or the launch file; logged once),
``rclpy.init``, construct, spin; an invalid configuration (``ValueError`` or
``ParameterException`` from the constructor) logs a fatal ``invalid configuration: ...`` and
exits with status 2; ROS that cannot start (``rclpy.init`` or the node's creation failing in
rcl, e.g. ``ROS_SECURITY_ENABLE=true`` with ``ROS_SECURITY_STRATEGY=Enforce`` and no keystore)
is one line on stderr (:func:`ros_start_error`: rcl's error and the likely cause) and status 2;
parameters given to the node that it does not declare (``-p kk:=3``, a misspelt name in a
``--params-file``) are warned about with the closest declared name (:func:`unknown_parameters`);
``KeyboardInterrupt`` and ``ExternalShutdownException`` end the spin quietly; the node is
destroyed and rclpy shut down in every case.

Callbacks. :func:`guarded` wraps a subscription, timer or service callback so that no exception
ever leaves it (rclpy would end the spin and the node with it): the error is logged (throttled,
with the traceback's last frame), reported to the node's ``on_error`` hook (a counter and a
diagnostics entry) and the callback returns its default (a service its response with
``success = False`` and the reason).

Logging. :class:`ThrottledLog` lets at most one line per kind through every ``period`` seconds
(steady time, any thread) and appends how many lines of that kind it suppressed since the last
one (the nodes also count every event on ``/diagnostics``).
"""

from __future__ import annotations

import difflib
import math
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)

__all__ = ["CLOCK_JUMP", "ParamSpec", "ThrottledLog", "declare_config", "descriptor", "guarded",
           "on_clock_jump_back", "parameter_values", "parameter_yaml", "ros_start_error",
           "run_node", "spec_note", "unknown_parameters"]

T = TypeVar("T")


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter.

    Attributes
    ----------
    name : str
        Dotted ROS name.
    default : Any
        Default value; its Python type is the parameter's type. None: no default, the type is
        ``type`` (e.g. an optional double array).
    description : str
        Purpose and unit.
    bounds : (low, high) or None
        Inclusive range (integer range for int defaults, floating point otherwise).
    read_only : bool
        Structural: set only at start-up.
    constraints : str
        ``additional_constraints`` text.
    type : int or None
        ``rcl_interfaces.msg.ParameterType`` when ``default`` is None (default: double array).
    """

    name: str
    default: Any
    description: str
    bounds: tuple[float, float] | None = None
    read_only: bool = False
    constraints: str = ""
    type: int | None = None


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ``ParameterDescriptor`` of a :class:`ParamSpec`."""
    desc = ParameterDescriptor(description=spec.description, read_only=spec.read_only,
                               additional_constraints=spec.constraints)
    if spec.default is None:
        desc.type = spec.type if spec.type is not None else ParameterType.PARAMETER_DOUBLE_ARRAY
    if spec.bounds is not None:
        low, high = spec.bounds
        if isinstance(spec.default, int) and not isinstance(spec.default, bool):
            desc.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        else:
            desc.floating_point_range = [FloatingPointRange(from_value=float(low),
                                                            to_value=float(high), step=0.0)]
    return desc


def parameter_values(node: Any, specs: Sequence[ParamSpec]) -> dict[str, Any]:
    """``{name: current value}`` of the table; a typed parameter without a value is None."""
    from rclpy.exceptions import ParameterUninitializedException

    values: dict[str, Any] = {}
    for spec in specs:
        try:
            values[spec.name] = node.get_parameter(spec.name).value
        except ParameterUninitializedException:
            values[spec.name] = None
    return values


def declare_config(node: Any, specs: Sequence[ParamSpec], build: Callable[[dict[str, Any]], T]
                   ) -> T:
    """Declare the table on ``node``, build its config, and validate every later set.

    Parameters
    ----------
    node : rclpy.node.Node
    specs : sequence of ParamSpec
    build : callable
        ``{name: value} -> config``; raises ``ValueError`` naming the bad parameter.

    Returns
    -------
    The config built from the start-up values.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        An invalid start-up value (the runner turns it into exit status 2).
    """
    from rclpy.parameter import Parameter

    for spec in specs:
        default = (Parameter.Type(spec.type if spec.type is not None
                                  else ParameterType.PARAMETER_DOUBLE_ARRAY)
                   if spec.default is None else spec.default)
        node.declare_parameter(spec.name, default, descriptor(spec))
    # What the node was started with (-p, --params-file) that it does not declare is ignored
    # by rclpy without a word: say so, with the closest name.
    for warning in unknown_parameters(getattr(node, "_parameter_overrides", {}),
                                      (spec.name for spec in specs)):
        node.get_logger().warning(warning)
    config = build(parameter_values(node, specs))
    names = {spec.name for spec in specs}

    def on_set(parameters: Iterable[Any]) -> SetParametersResult:
        changed = {p.name: p.value for p in parameters if p.name in names}
        if not changed:
            return SetParametersResult(successful=True)
        try:
            build({**parameter_values(node, specs), **changed})
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    node.add_on_set_parameters_callback(on_set)
    return config


class ThrottledLog:
    """At most one line per kind every ``period`` s (steady time, thread-safe); counts the rest.

    Parameters
    ----------
    logger : rclpy logger
        ``node.get_logger()``.
    period : float
        Seconds between two lines of one kind.
    """

    def __init__(self, logger: Any, period: float) -> None:
        self.logger = logger
        self.period = float(period)
        self._state: dict[str, tuple[float, int]] = {}
        self._lock = threading.Lock()

    def allow(self, kind: str) -> tuple[bool, int]:
        """(log now?, lines of this kind suppressed since the last one logged)."""
        now = time.monotonic()
        with self._lock:
            last, suppressed = self._state.get(kind, (-math.inf, 0))
            if now - last < self.period:
                self._state[kind] = (last, suppressed + 1)
                return False, 0
            self._state[kind] = (now, 0)
        return True, suppressed

    def info(self, kind: str, message: str) -> bool:
        """Log ``message`` at info level unless throttled; True if it was logged."""
        text = self._text(kind, message)
        if text is not None:
            self.logger.info(text)
        return text is not None

    def warning(self, kind: str, message: str) -> bool:
        """Log ``message`` as a warning unless throttled; True if it was logged."""
        text = self._text(kind, message)
        if text is not None:
            self.logger.warning(text)
        return text is not None

    def error(self, kind: str, message: str) -> bool:
        """Log ``message`` as an error unless throttled; True if it was logged."""
        text = self._text(kind, message)
        if text is not None:
            self.logger.error(text)
        return text is not None

    def _text(self, kind: str, message: str) -> str | None:
        log, suppressed = self.allow(kind)
        if not log:
            return None
        if suppressed:
            message += f" ({suppressed} similar message(s) suppressed)"
        return message


def guarded(callback: Callable[..., Any], log: ThrottledLog,
            on_error: Callable[[str, str], None] | None = None,
            name: str | None = None) -> Callable[..., Any]:
    """``callback`` that never raises (module docstring).

    Parameters
    ----------
    callback : callable
        A subscription callback ``f(msg)``, timer callback ``f()`` or service callback
        ``f(request, response)``.
    log : ThrottledLog
        Where the error is logged (kind ``callback:<name>``).
    on_error : callable, optional
        ``on_error(name, message)`` after the error is logged (count it, report it); its own
        exceptions are swallowed too.
    name : str, optional
        Names the callback in the log (default: its ``__name__``).

    Returns
    -------
    callable
        Same signature; returns ``callback``'s result, or on an exception None (a service: the
        ``response`` argument with ``success = False`` and ``message`` set when it has them).
    """
    label = name or getattr(callback, "__name__", "callback")

    def wrapper(*args: Any) -> Any:
        try:
            return callback(*args)
        except Exception as exc:  # noqa: BLE001 - the point: nothing escapes a callback
            tb = exc.__traceback__
            while tb is not None and tb.tb_next is not None:
                tb = tb.tb_next
            where = f" at {tb.tb_frame.f_code.co_filename}:{tb.tb_lineno}" if tb else ""
            message = f"{type(exc).__name__}: {exc}"[:500]
            log.error(f"callback:{label}", f"{label} failed ({message}){where}; input "
                      "dropped, node keeps running")
            if on_error is not None:
                try:
                    on_error(label, message)
                except Exception:  # noqa: BLE001, S110 - reporting must not raise either
                    pass
            if len(args) == 2 and hasattr(args[1], "success"):  # a service response
                response = args[1]
                response.success = False
                if hasattr(response, "message"):
                    response.message = f"{label} failed: {message}"
                return response
            return None

    wrapper.__name__ = label
    wrapper.__doc__ = callback.__doc__
    return wrapper


def run_node(factory: Callable[[], Any], name: str, args: list[str] | None = None) -> None:
    """The Jazzy ``main()``: init, construct with ``factory()``, spin, clean up.

    Raises
    ------
    SystemExit
        Status 2 after a fatal ``invalid configuration`` log when ``factory`` raises
        ``ValueError`` or ``rclpy.exceptions.ParameterException``.
    """
    import rclpy
    from rclpy.exceptions import ParameterException
    from rclpy.executors import ExternalShutdownException
    from rclpy.impl.implementation_singleton import rclpy_implementation

    from push_ros.dds import apply_default_profile, describe

    apply_default_profile()  # before rclpy.init: Fast DDS reads it when the participant is made
    try:
        rclpy.init(args=args)
    except rclpy_implementation.RCLError as exc:
        print(f"{name}: {ros_start_error(exc)}", file=sys.stderr)
        raise SystemExit(2) from None
    rclpy.logging.get_logger(name).info(describe())
    try:
        node = factory()
    except (ValueError, ParameterException) as exc:
        rclpy.logging.get_logger(name).fatal(f"invalid configuration: {exc}")
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    except rclpy_implementation.RCLError as exc:
        print(f"{name}: {ros_start_error(exc)}", file=sys.stderr)
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def ros_start_error(exc: BaseException) -> str:
    """One line for ROS that would not start (``rclpy.init`` or a node's creation failed in
    rcl): rcl's first error line and the likely cause read from the environment."""
    text = (str(exc).splitlines() or [type(exc).__name__])[0][:300]
    if os.environ.get("ROS_SECURITY_ENABLE", "").strip().lower() == "true":
        strategy = os.environ.get("ROS_SECURITY_STRATEGY", "") or "Permissive"
        keystore = os.environ.get("ROS_SECURITY_KEYSTORE", "")
        cause = (f"ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY={strategy}, "
                 + (f"keystore {keystore}" if keystore else "no ROS_SECURITY_KEYSTORE")
                 + ": DDS-Security needs a keystore with this node's enclave and a Fast DDS "
                 "built with security, which the pip install does not have; unset "
                 "ROS_SECURITY_ENABLE, or see docs/SECURITY.md")
    else:
        cause = ("check ROS_DOMAIN_ID (0-232), RMW_IMPLEMENTATION and the DDS profile: "
                 "pushbot doctor")
    return f"cannot start ROS: {text} ({cause})"


#: Parameters every rclpy node has without declaring them in its table.
ROS_PARAMETERS = ("use_sim_time", "start_type_description_service")


def unknown_parameters(given: Iterable[str], known: Iterable[str]) -> list[str]:
    """A warning per parameter name in ``given`` (what the node was started with: ``-p``,
    ``--params-file``) that is not in ``known`` (its table and :data:`ROS_PARAMETERS`),
    with the closest known name when one is close (``difflib``, ratio 0.6)."""
    names = sorted({*known, *ROS_PARAMETERS})
    out = []
    for name in sorted(set(given) - set(names)):
        close = difflib.get_close_matches(name, names, n=1)
        out.append(f"unknown parameter {name[:100]!r} ignored"
                   + (f" (did you mean {close[0]!r}?)" if close else
                      f" (not a parameter of this node; its parameters: "
                      f"{', '.join(names)[:400]})"))
    return out


#: A node's clock jumping back by more than this (s) is a restarted time source (a restarted
#: simulator starts near 0), not jitter: ``push_core.episode.PREVIOUS_EPISODE_WINDOW``.
CLOCK_JUMP = 2.0


def on_clock_jump_back(node: Any, callback: Callable[[float], None]) -> Any:
    """Call ``callback(delta)`` (``delta`` < 0, s) when ``node``'s clock jumps back by more
    than :data:`CLOCK_JUMP` (a restarted simulator): the stamps of the old clock then mean
    nothing to the node's input rules. Returns the jump handle (keep it: the callback lives as
    long as the handle), after logging the jump at warning level."""
    from rclpy.clock import JumpThreshold
    from rclpy.duration import Duration

    def on_jump(jump: Any) -> None:
        delta = jump.delta.nanoseconds * 1e-9
        node.get_logger().warning(f"the clock jumped back by {-delta:.3f} s (a restarted "
                                  "simulator?): the stamps of the old clock are forgotten")
        callback(delta)

    return node.get_clock().create_jump_callback(
        JumpThreshold(min_forward=None, min_backward=Duration(seconds=-CLOCK_JUMP),
                      on_clock_change=False), post_callback=on_jump)


def _yaml_value(value: Any) -> str:
    """A default as a ROS parameter YAML value (doubles keep their decimal point)."""
    import json

    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):  # YAML 1.1 reads 1e-05 as a string: write 1.0e-05
        text = repr(value)
        mantissa, e, exponent = text.partition("e")
        return f"{mantissa}.0e{exponent}" if e and "." not in mantissa else text
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_yaml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return json.dumps(value)
    return str(value)


def spec_note(spec: ParamSpec) -> str:
    """The documentation of one parameter: its description, then its range, constraints and
    "Read-only." (the text of the parameter files and of docs/INTERFACES.md)."""
    note = spec.description
    if spec.bounds is not None:
        note += f" Range [{spec.bounds[0]:g}, {spec.bounds[1]:g}]."
    if spec.constraints:
        note += f" Constraint: {spec.constraints}."
    if spec.read_only:
        note += " Read-only."
    return note


def parameter_yaml(node_name: str, specs: Sequence[ParamSpec], header: str = "",
                   notes: Mapping[str, str] | None = None) -> str:
    """A node's parameter file generated from its table: every parameter at its default, its
    description (and bounds, read-only) as the comment above it; dotted names nested.

    Parameters
    ----------
    node_name : str
        The file's top-level key (``--params-file`` reaches the node of that name).
    specs : sequence of ParamSpec
    header : str
        Comment lines for the top of the file (without ``#``).
    notes : mapping, optional
        ``{parameter name: text}``: a comment paragraph (a blank line, then the wrapped text)
        written before that parameter (and before its group's key when it opens a group).

    Returns
    -------
    str
        YAML text; a parameter without a default is written as a comment only.

    Raises
    ------
    ValueError
        A name nested deeper than ``group.name``, a group whose parameters are not listed
        together (YAML would get the group twice), or a note naming no parameter.
    """
    import textwrap

    seen: set[str] = set()

    out = [f"# {line}".rstrip() for line in header.strip().splitlines()] if header else []
    out += [f"{node_name}:", "  ros__parameters:"]
    group = ""
    notes = dict(notes or {})
    unknown = set(notes) - {spec.name for spec in specs}
    if unknown:
        raise ValueError(f"notes for unknown parameters: {sorted(unknown)}")
    for spec in specs:
        prefix, _, leaf = spec.name.rpartition(".")
        if spec.name in notes:
            indent = "      " if prefix and prefix == group else "    "
            if not out[-1].endswith("ros__parameters:"):
                out.append("")
            out += textwrap.wrap(notes[spec.name], 96 - len(indent),
                                 initial_indent=f"{indent}# ", subsequent_indent=f"{indent}# ")
        if "." in prefix:
            raise ValueError(f"parameter {spec.name!r}: only one level of nesting is written")
        if prefix != group:
            if prefix in seen:
                raise ValueError(f"parameter {spec.name!r}: group {prefix!r} is split")
            if prefix:
                out.append(f"    {prefix}:")
                seen.add(prefix)
            group = prefix
        indent = "      " if prefix else "    "
        out += textwrap.wrap(spec_note(spec), 96 - len(indent), initial_indent=f"{indent}# ",
                             subsequent_indent=f"{indent}# ")
        if spec.default is None:
            out.append(f"{indent}# {leaf}: (no default)")
        else:
            out.append(f"{indent}{leaf}: {_yaml_value(spec.default)}")
    return "\n".join(out) + "\n"
