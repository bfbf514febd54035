"""The running graph as the calibration procedure's robot (``pushbot calibrate``).

:class:`GraphRobot` is :class:`pushbot.runner.calibration.CalibrationRobot` over ROS: a move is
a goal on ``executor/joint_goal`` (sent once ``executor/status`` says the executor is ready, or
disabled: the dry run plans it and refuses), waited for on ``executor/goal_result``; the view's
frame is the first ``camera/color/image_raw`` stamped after the arm is held at the goal
(:data:`HELD_STATES` joint states received after the answer within :data:`HELD` rad of each
other: the executor answers ``reached`` when its plan's time is over and the arm tracks it,
which on a loaded machine is before the arm has settled, and this process may not yet have read
the joint states the executor judged by); the joints are the newest ``/joint_states`` (held);
the arm's model is the executor's (its ``/robot_description`` and parameters, read through its
parameter services).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.calibration import CalibrationRefused
from push_ros.frames import CAMERA_FRAME, WORLD_FRAME

__all__ = ["GraphRobot"]

#: Longest wait for the graph's inputs (camera_info, the model, the first joint state), s.
INPUT_TIMEOUT = 20.0
#: The arm counts as held at a goal after this many joint states within ``HELD`` rad of each
#: other (push_executor's own rule for a held arm, ``MeasuredArm``).
HELD_STATES, HELD = 3, 1e-4


def _stamp(msg: Any) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


class GraphRobot:
    """The executor, ``/joint_states`` and the colour camera of the running graph.

    Parameters
    ----------
    node, executor
        A CLI node and its executor (:func:`pushbot.ros2cli.discovery.cli_node`).
    executor_name : str
        The executor node's name (its parameter services).
    move_timeout : float
        Longest wait for one move (readiness, the answer, the frame after it), s.
    """

    def __init__(self, node: Any, executor: Any, executor_name: str,
                 move_timeout: float) -> None:
        from diagnostic_msgs.msg import DiagnosticStatus
        from sensor_msgs.msg import CameraInfo, Image, JointState
        from std_msgs.msg import String

        from push_ros.qos import JOINT_STATE_QOS, LATCHED_QOS, RELIABLE_QOS, SENSOR_QOS

        self.node, self.executor, self.name = node, executor, executor_name
        self.move_timeout = float(move_timeout)
        self.world_frame, self.camera_frame = WORLD_FRAME, CAMERA_FRAME
        self.robot_time = 0.0
        self.arm: Any = None
        self.params: Any = None
        self._urdf = ""
        self._joint_msg: Any = None
        self._image: Any = None
        self._info: Any = None
        self._status: dict[str, str] = {}
        self._results: dict[str, Any] = {}
        self._frame: NDArray[np.uint8] | None = None
        self._moved = False
        self._JointState = JointState
        sub = node.create_subscription
        sub(String, "/robot_description", lambda m: setattr(self, "_urdf", m.data), LATCHED_QOS)
        self._recent: deque[Any] = deque(maxlen=HELD_STATES)
        sub(JointState, "/joint_states", self._on_joints, JOINT_STATE_QOS)
        sub(Image, "camera/color/image_raw", lambda m: setattr(self, "_image", m), SENSOR_QOS)
        sub(CameraInfo, "camera/color/camera_info", lambda m: setattr(self, "_info", m),
            SENSOR_QOS)
        sub(DiagnosticStatus, "executor/status", self._on_status, LATCHED_QOS)
        sub(DiagnosticStatus, "executor/goal_result", self._on_result, RELIABLE_QOS)
        self._pub_goal = node.create_publisher(JointState, "executor/joint_goal", RELIABLE_QOS)

    # ---- inputs ------------------------------------------------------------------------------
    def _on_joints(self, msg: Any) -> None:
        self._joint_msg = msg
        self._recent.append(msg)

    def _held(self) -> bool:
        """The last :data:`HELD_STATES` joint states received (since the deque was cleared)
        within :data:`HELD` rad of each other."""
        if len(self._recent) < HELD_STATES:
            return False
        try:
            q = np.array([self._posture(m) for m in self._recent])
        except CalibrationRefused:
            return False
        return bool(np.ptp(q, axis=0).max() <= HELD)

    def _on_status(self, msg: Any) -> None:
        self._status = {kv.key: kv.value for kv in msg.values[:64]}

    def _on_result(self, msg: Any) -> None:
        from push_ros.refusal import read_refusal

        try:
            answer = read_refusal(msg)
        except ValueError:
            return
        self._results[answer.push_stamp] = answer

    def _wait(self, predicate: Callable[[], Any], timeout: float) -> bool:
        from pushbot.ros2cli.discovery import spin_until

        return spin_until(self.executor, predicate, time.monotonic() + timeout, 0.01)

    def _need(self, predicate: Callable[[], Any], what: str) -> None:
        if not self._wait(predicate, INPUT_TIMEOUT):
            raise CalibrationRefused("robot", f"no {what} within {INPUT_TIMEOUT:g} s: is the "
                                     "graph running (pushbot up)?")

    def intrinsics(self) -> tuple[NDArray[np.float64], tuple[float, ...], tuple[int, int]]:
        """``K`` (3, 3), the distortion and (width, height) from ``camera_info``."""
        from push_ros.images import camera_matrix_from_info

        self._need(lambda: self._info is not None, "camera/color/camera_info")
        info = self._info
        self.camera_frame = info.header.frame_id or CAMERA_FRAME
        d = tuple(float(v) for v in info.d)
        return (camera_matrix_from_info(info), d if any(d) else (),
                (int(info.width), int(info.height)))

    def _model(self) -> None:
        from rclpy.parameter import parameter_value_to_python
        from rclpy.parameter_client import AsyncParameterClient

        from push_executor.kinematics import ArmKinematics
        from push_executor.parameters import PARAMETERS, ExecutorParams

        client = AsyncParameterClient(self.node, self.name)
        if not client.wait_for_services(INPUT_TIMEOUT):
            raise CalibrationRefused("robot", f"no parameter services of {self.name} within "
                                     f"{INPUT_TIMEOUT:g} s: is the executor running?")
        values: dict[str, Any] = {}
        for spec in PARAMETERS:  # one by one: an unset one (joints) empties a joint answer
            future = client.get_parameters([spec.name])
            self._need(future.done, f"answer from {self.name}/get_parameters")
            answer = future.result().values
            values[spec.name] = parameter_value_to_python(answer[0]) if answer else spec.default
        self.params = ExecutorParams.from_values(values)
        self.world_frame = str(values["world_frame"])
        self._need(lambda: self._urdf, "/robot_description")
        p = self.params.values
        self.arm = ArmKinematics(self._urdf, p["base_frame"], self.params.tool, p["base_pose"],
                                 p["acceleration_limits"], p["jerk_limits"])

    # ---- the procedure's robot ---------------------------------------------------------------
    def calibrate(self, setup: Any, log: Callable[[str], None]) -> Any:
        """Run :func:`pushbot.runner.calibration.run_calibration` on the graph."""
        from pushbot.runner.calibration import run_calibration

        self._model()
        self._need(lambda: self._joint_msg is not None, "/joint_states")
        return run_calibration(self, self.arm, setup, self.params.motion, log)

    def joints(self) -> NDArray[np.float64]:
        return self._posture(self._joint_msg)

    def _posture(self, msg: Any) -> NDArray[np.float64]:
        by_name = dict(zip(msg.name, msg.position, strict=False))
        missing = [j for j in self.arm.joint_names if j not in by_name]
        if missing:
            raise CalibrationRefused("robot", f"/joint_states lacks the joints {missing}")
        return np.array([by_name[j] for j in self.arm.joint_names], dtype=float)

    def move(self, q: NDArray[np.float64]) -> tuple[str, str]:
        from push_ros.refusal import stamp_key

        t0 = time.monotonic()
        try:
            return self._move(q, stamp_key)
        finally:
            self.robot_time += time.monotonic() - t0

    def _move(self, q: NDArray[np.float64], stamp_key: Callable[[Any], str]) -> tuple[str, str]:
        def ready() -> bool:
            return (self._status.get("ready") == "true"
                    or self._status.get("unavailable", "").startswith("disabled"))

        if not self._wait(ready, self.move_timeout):
            return "timeout", (f"the executor was not ready within {self.move_timeout:g} s: "
                               f"{self._status.get('unavailable') or 'no executor/status'}")
        msg = self._JointState(name=list(self.arm.joint_names),
                               position=[float(v) for v in q])
        msg.header.stamp = self.node.get_clock().now().to_msg()
        key = stamp_key(msg.header.stamp)
        self._pub_goal.publish(msg)
        if not self._wait(lambda: key in self._results, self.move_timeout):
            return "timeout", f"no answer on executor/goal_result within {self.move_timeout:g} s"
        answer = self._results.pop(key)
        if answer.kind != "reached":
            return answer.kind, answer.reason
        self._recent.clear()
        if not self._wait(self._held, self.move_timeout):
            return "timeout", f"the arm was not held at the goal within {self.move_timeout:g} s"
        reached = _stamp(self._recent[-1])
        if not self._wait(lambda: self._image is not None and _stamp(self._image) > reached,
                          self.move_timeout):
            return "timeout", "no colour frame after the move"
        self._frame, self._moved = self._rgb(self._image), True
        return "", ""

    @staticmethod
    def _rgb(msg: Any) -> NDArray[np.uint8]:
        from push_ros.images import image_to_array

        image = image_to_array(msg)
        if msg.encoding == "bgr8":
            image = image[..., ::-1]
        elif image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        return np.ascontiguousarray(image)

    def frame(self) -> NDArray[np.uint8]:
        if self._frame is None:
            raise CalibrationRefused("robot", "no colour frame yet")
        return self._frame

    def park(self) -> None:
        """Back to the executor's park posture (best effort: once more after a stop on the
        way; a refusal is only printed)."""
        if not self._moved:  # nothing moved (a dry run, a refused first pose)
            return
        park = np.array(self.params.motion.park_positions, dtype=float)
        kind, reason = self.move(park)
        if kind == "fault":  # stopped on the way (a tracking deviation): again from there
            print(f"pushbot calibrate: parking stopped ({reason}); parking again")
            kind, reason = self.move(park)
        if kind:
            print(f"pushbot calibrate: the arm did not park ({kind}): {reason}")
