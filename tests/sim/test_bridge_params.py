"""Every parameter of ``sim_bridge_node`` has a value and survives a dump and reload: an
in-process node and a client calling its parameter services over DDS, as ``ros2 param dump`` /
``ros2 param load`` do. A parameter declared without a value made rclpy answer an empty list to
any ``get_parameters`` naming it."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = [pytest.mark.ros]

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("pybullet")

from rcl_interfaces.msg import Parameter as ParameterMsg  # noqa: E402
from rcl_interfaces.msg import ParameterType  # noqa: E402
from rcl_interfaces.srv import (  # noqa: E402
    DescribeParameters,
    GetParameters,
    ListParameters,
    SetParameters,
)
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from sim_bridge.params import PARAMETERS  # noqa: E402
from sim_bridge.sim_bridge_node import SimBridgeNode  # noqa: E402

NAME = "dump_sim_bridge_node"
OVERRIDES = [Parameter("image_width", value=160), Parameter("image_height", value=120),
             Parameter("object", value="rect1")]


def _call(client_node: Any, executor: Any, srv: Any, service: str, request: Any) -> Any:
    client = client_node.create_client(srv, f"/{NAME}/{service}")
    assert client.wait_for_service(timeout_sec=10.0), service
    future = client.call_async(request)
    executor.spin_until_future_complete(future, timeout_sec=20.0)
    assert future.done(), f"{service} did not answer"
    return future.result()


def test_every_parameter_has_a_value_and_a_dump_loads_back_unchanged(ros_context: Any) -> None:
    node = SimBridgeNode(node_name=NAME, context=ros_context, parameter_overrides=OVERRIDES)
    client = rclpy.create_node("dump_client", context=ros_context)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(client)
    try:
        names = list(_call(client, executor, ListParameters, "list_parameters",
                           ListParameters.Request()).result.names)
        assert {spec.name for spec in PARAMETERS} | {"use_sim_time"} <= set(names)
        dump = _call(client, executor, GetParameters, "get_parameters",
                     GetParameters.Request(names=names)).values
        assert len(dump) == len(names)  # an unset parameter makes rclpy answer []
        unset = [n for n, v in zip(names, dump, strict=True)
                 if v.type == ParameterType.PARAMETER_NOT_SET]
        assert unset == []
        values = dict(zip(names, dump, strict=True))
        assert values["use_com_offset"].bool_value is False
        assert list(values["com_offset"].double_array_value) == [0.0, 0.0]
        assert values["object"].string_value == "rect1"

        described = _call(client, executor, DescribeParameters, "describe_parameters",
                          DescribeParameters.Request(names=names)).descriptors
        read_only = {d.name for d in described if d.read_only}
        assert {"idle_frame_rate", "clock_rate"} <= read_only
        results = _call(client, executor, SetParameters, "set_parameters",
                        SetParameters.Request(parameters=[
                            ParameterMsg(name=n, value=v) for n, v in values.items()])).results
        for name, result in zip(names, results, strict=True):
            if name in read_only:  # structural: refused as rclpy refuses every read-only set
                assert not result.successful and "read-only" in result.reason, name
            else:
                assert result.successful, (name, result.reason)
        again = _call(client, executor, GetParameters, "get_parameters",
                      GetParameters.Request(names=names)).values
        assert list(again) == list(dump)
        # The bridge still builds its scene from the reloaded values.
        response = node.on_reset(*_trigger())
        assert response.success, response.message
    finally:
        executor.shutdown()
        client.destroy_node()
        node.destroy_node()


def test_com_offset_is_used_only_when_asked(ros_context: Any) -> None:
    com = Parameter("com_offset", value=[0.01, -0.005])
    node = SimBridgeNode(node_name="com_sim_bridge_node", context=ros_context,
                         parameter_overrides=[*OVERRIDES, com])
    try:
        assert node._params.com_offset is None  # use_com_offset false: the spec's COM
        assert node.set_parameters([Parameter("use_com_offset", value=True)])[0].successful
        response = node.on_reset(*_trigger())
        assert response.success and "COM (0.0100, -0.0050) m" in response.message, response
        refused = node.set_parameters([Parameter("com_offset", value=[0.01])])[0]
        assert not refused.successful and "com_offset" in refused.reason
    finally:
        node.destroy_node()


def _trigger() -> tuple[Any, Any]:
    from std_srvs.srv import Trigger

    return Trigger.Request(), Trigger.Response()
