"""push_ros.node: parameter table -> descriptors -> typed config with on-set validation,
throttled logging, and the frame / QoS constants (in-process, real rclpy nodes)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pytest
from rcl_interfaces.msg import ParameterType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

from push_ros.frames import CAMERA_FRAME, OBJECT_FRAME, WORLD_FRAME
from push_ros.node import (
    ParamSpec,
    ThrottledLog,
    declare_config,
    descriptor,
    guarded,
    parameter_values,
)
from push_ros.qos import LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS, latched_reader_qos

pytestmark = pytest.mark.ros

SPECS = (
    ParamSpec("gain", 2.0, "A gain, 1/s.", (0.0, 10.0)),
    ParamSpec("count", 3, "A count.", (1, 100)),
    ParamSpec("low", 1.0, "Lower bound, m."),
    ParamSpec("high", 2.0, "Upper bound, m."),
    ParamSpec("frame", "world", "A frame.", read_only=True),
    ParamSpec("offset", None, "Optional (x, y), m.", constraints="2 values or empty"),
)


@dataclass(frozen=True)
class Config:
    gain: float
    count: int
    low: float
    high: float
    frame: str
    offset: tuple[float, ...] | None

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> Config:
        if not values["low"] < values["high"]:
            raise ValueError(f"parameter 'low' must be < 'high', got {values['low']} and "
                             f"{values['high']}")
        offset = values["offset"]
        return cls(float(values["gain"]), int(values["count"]), float(values["low"]),
                   float(values["high"]), str(values["frame"]),
                   tuple(offset) if offset is not None and len(offset) else None)


def test_descriptors_carry_ranges_types_and_flags() -> None:
    gain, count, _, _, frame, offset = (descriptor(s) for s in SPECS)
    assert gain.floating_point_range[0].to_value == 10.0 and not gain.integer_range
    assert count.integer_range[0].from_value == 1 and not count.floating_point_range
    assert frame.read_only and not gain.read_only
    assert offset.type == ParameterType.PARAMETER_DOUBLE_ARRAY
    assert offset.additional_constraints == "2 values or empty"


def test_config_is_built_at_start_up_and_every_set_is_validated(ros_context: Any) -> None:
    node = Node("helpers_test", context=ros_context,
                parameter_overrides=[Parameter("count", value=7)])
    try:
        config = declare_config(node, SPECS, Config.from_values)
        assert config == Config(2.0, 7, 1.0, 2.0, "world", None)
        assert parameter_values(node, SPECS)["offset"] is None  # typed, no value
        # A valid set succeeds (when it takes effect is the node's business).
        assert node.set_parameters([Parameter("gain", value=3.0)])[0].successful
        # A set that makes the whole configuration invalid is refused with the reason ...
        result = node.set_parameters([Parameter("low", value=5.0)])[0]
        assert not result.successful and "parameter 'low' must be < 'high'" in result.reason
        assert node.get_parameter("low").value == 1.0  # ... and changes nothing
        # ... but a set that fixes it together with another value is one atomic check.
        results = node.set_parameters_atomically([Parameter("low", value=5.0),
                                                  Parameter("high", value=6.0)])
        assert results.successful
        # The descriptors still apply: out of range, read only.
        assert not node.set_parameters([Parameter("gain", value=11.0)])[0].successful
        assert not node.set_parameters([Parameter("frame", value="map")])[0].successful
        # Parameters outside the table are not the callback's business.
        assert node.set_parameters([Parameter("use_sim_time", value=True)])[0].successful
    finally:
        node.destroy_node()


def test_an_invalid_start_up_value_raises(ros_context: Any) -> None:
    node = Node("helpers_bad", context=ros_context,
                parameter_overrides=[Parameter("low", value=3.0)])
    try:
        with pytest.raises(ValueError, match="parameter 'low'"):
            declare_config(node, SPECS, Config.from_values)
    finally:
        node.destroy_node()


class _Logger:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def warning(self, text: str) -> None:
        self.lines.append(("warning", text))

    def error(self, text: str) -> None:
        self.lines.append(("error", text))


def test_throttled_log_counts_what_it_suppressed() -> None:
    logger = _Logger()
    log = ThrottledLog(logger, period=math.inf)  # only the first line of each kind
    assert log.warning("a", "first a")
    assert not log.warning("a", "second a") and not log.error("a", "third a")
    assert log.error("b", "first b")
    assert logger.lines == [("warning", "first a"), ("error", "first b")]
    log.period = 0.0  # the next line of kind a is due: it says how many it stood for
    assert log.warning("a", "fourth a")
    assert logger.lines[-1] == ("warning", "fourth a (2 similar message(s) suppressed)")


def test_guarded_callbacks_never_raise_and_report_the_error() -> None:
    from std_srvs.srv import Trigger

    logger, errors = _Logger(), []
    log = ThrottledLog(logger, period=0.0)

    def on_msg(msg: int) -> int:
        return 10 // msg

    def on_reset(request: Any, response: Any) -> Any:
        raise ValueError("boom")

    cb = guarded(on_msg, log, lambda name, text: errors.append((name, text)))
    assert cb(2) == 5 and errors == []  # passes results through
    assert cb(0) is None  # ZeroDivisionError: swallowed
    assert errors == [("on_msg", "ZeroDivisionError: integer division or modulo by zero")]
    assert logger.lines[-1][0] == "error" and "on_msg failed (ZeroDivisionError" in \
        logger.lines[-1][1] and "node keeps running" in logger.lines[-1][1]
    service = guarded(on_reset, log, lambda name, text: 1 / 0)  # a failing hook too
    response = service(Trigger.Request(), Trigger.Response())
    assert response.success is False and response.message == "on_reset failed: ValueError: boom"


def test_frames_and_qos_profiles() -> None:
    assert (WORLD_FRAME, CAMERA_FRAME, OBJECT_FRAME) == (
        "world", "camera_color_optical_frame", "object")
    assert SENSOR_QOS.reliability == ReliabilityPolicy.BEST_EFFORT
    assert RELIABLE_QOS.durability == DurabilityPolicy.VOLATILE and RELIABLE_QOS.depth == 10
    assert LATCHED_QOS.durability == DurabilityPolicy.TRANSIENT_LOCAL and LATCHED_QOS.depth == 1
    reader = latched_reader_qos(25)
    assert (reader.durability, reader.reliability, reader.depth) == (
        DurabilityPolicy.TRANSIENT_LOCAL, ReliabilityPolicy.RELIABLE, 25)
