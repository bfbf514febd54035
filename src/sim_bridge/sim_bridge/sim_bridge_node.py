"""``sim_bridge_node``: the simulated robot and RGB-D camera behind standard ROS 2 topics.

Role: a thin ROS wrapper around :class:`sim_bridge.world.PushWorld` (pybullet, DIRECT mode): a
table, one flat object, a pusher (or a Panda arm, :mod:`sim_bridge.arm_ros`) and a D415-like
camera. Parameters: :mod:`sim_bridge.params`.

Invariants:

- The node owns ``/clock`` (published time = ``epoch + world.sim_time``, never going back,
  also across resets; :class:`sim_bridge.worker.Timeline`); it never runs on sim time itself.
- Every pybullet call runs in one worker thread, one job at a time; a command arriving while it
  is busy is refused, never queued (:class:`sim_bridge.worker.Worker`). After a job the worker
  is idle *before* its results go out.
- No exception leaves a callback; health, refusals and counters are
  :class:`push_ros.health.NodeHealth`'s (``/diagnostics``).

Topics, services, fault injection and parameters: docs/INTERFACES.md; the simulator:
docs/design/sim-world.md, docs/design/node-runtime.md and docs/design/arm.md.
"""

from __future__ import annotations

import time
import traceback
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_srvs.srv import Trigger

from push_ros.frames import WORLD_FRAME
from push_ros.health import MAX_TEXT, NodeHealth
from push_ros.node import declare_config, parameter_values, run_node
from push_ros.paths import push_points_from_path
from push_ros.poses import check_frame, xytheta_from_pose
from push_ros.qos import RELIABLE_QOS
from push_ros.stamps import stamp_from_seconds
from sim_bridge import commands
from sim_bridge.arm_ros import ArmEndpoints
from sim_bridge.faults import FaultInjector
from sim_bridge.params import NODE_NAME, PARAMETERS, SimBridgeParams
from sim_bridge.resting import Rest
from sim_bridge.scene_ros import Capture, SceneEndpoints
from sim_bridge.worker import Timeline, Worker
from sim_bridge.world import PushWorld, WorldConfig

__all__ = ["SimBridgeNode", "main"]

#: Seconds between repeated log lines of the same kind (the diagnostics count every event).
LOG_THROTTLE_S = 1.0
#: Period of the regular /diagnostics message, seconds of wall time.
DIAGNOSTICS_PERIOD_S = 1.0


class SimBridgeNode(Node):
    """ROS wrapper of :class:`~sim_bridge.world.PushWorld`; see the module docstring.

    Raises
    ------
    ValueError, rclpy.exceptions.ParameterException
        At construction, if a parameter is invalid or the world cannot be built.
    """

    def __init__(self, node_name: str = NODE_NAME, **kwargs: Any) -> None:
        super().__init__(node_name, **kwargs)
        self.health = NodeHealth(self, "simulation", "pybullet", commands.COUNTERS, LOG_THROTTLE_S,
                                 on_error=self._on_callback_error)
        self._params = declare_config(self, PARAMETERS, SimBridgeParams.from_values)
        self._problem = ""  # the last command's refusal or failure; "" after a success
        self._pushing = False  # the physics runs a push or an arm run (/clock follows it)
        self._closing = False  # destroy_node has begun: nothing more is published
        self.faults: FaultInjector[Capture] = FaultInjector(self._params.faults,
                                                            self.health.count)
        self.scene = SceneEndpoints(self, Timeline(), lambda: self._closing,
                                    lambda c: self.faults.frames(c, c.time), self.health.log)
        self.timeline = self.scene.timeline
        self._capture: Capture | None = None
        self._next_idle_clock = 0.0  # monotonic s: the next resting /clock is due then
        self.worker = Worker()  # every pybullet call happens in its one thread
        self.rest = Rest(self.worker)  # time and still frames while no job runs
        try:
            self._world = self.worker.call(PushWorld, self._params.world_config()).result()
        except BaseException:
            self.worker.shutdown()
            raise

        # The guarded callables are attributes so tests can call them with real messages.
        guard = self.health.guard
        self.on_push = guard(self._on_push)
        self.on_knock = guard(self._on_knock)
        self.on_reset = guard(self._on_reset)
        self.create_subscription(Path, "planner/push", self.on_push, RELIABLE_QOS)
        self.create_subscription(PoseStamped, "sim/knock", self.on_knock, RELIABLE_QOS)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self._arm: ArmEndpoints | None = None
        if self._params.robot == "arm":
            self._arm = ArmEndpoints(
                self,
                controller_topic=self._params.arm_controller_topic,
                max_duration=self._params.arm_max_duration,
                timeline=self.timeline,
                sim_time=lambda: self._world.sim_time,
                health=self.health,
                guard=guard,
                on_rejected=self._refuse_trajectory,
                worker=self.worker,
                run=self._run_arm,
                closing=lambda: self._closing,
                scene=self.scene)

        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(1.0 / self._params.clock_rate, guard(self._on_clock_timer),
                          clock=steady)
        self.create_timer(1.0 / self._params.idle_frame_rate, guard(self._on_idle_timer),
                          clock=steady)
        self.create_timer(DIAGNOSTICS_PERIOD_S, guard(self._publish_diagnostics), clock=steady)
        self._warn(commands.startup_warnings(parameter_values(self, PARAMETERS),
                                             bool(self.get_parameter("use_sim_time").value)))
        self.worker.call(self._after_build).result()
        self.get_logger().info(f"sim bridge ready: {self._params.summary()}")

    # ---- health --------------------------------------------------------------------------
    def _on_callback_error(self, name: str, message: str) -> None:
        """An exception reached the guard (counted and logged by it): report it."""
        self._problem = f"{name} failed: {message}"
        self._publish_diagnostics()

    def _refuse(self, what: str, reason: str, kind: str, counter: str,
                push_stamp: Any = None) -> str:
        """Count (``counter``, ``refused_<kind>``), log and report a refused command; a push
        (``push_stamp`` given) is also answered on ``pusher/refused``."""
        self.health.count(counter)
        self._problem = self.health.refuse(what, reason, kind)
        if push_stamp is not None:
            self.scene.refusal(push_stamp, kind, self._problem)
        self._publish_diagnostics()
        return self._problem

    def _refuse_trajectory(self, kind: str, reason: str) -> None:
        """A joint trajectory the arm endpoints refused (counted as rejected)."""
        self._refuse("trajectory", reason, kind, "trajectories_rejected")

    def _started(self, busy: str, what: str, note: str, counter: str,
                 push_stamp: Any = None) -> None:
        """Report a started job, or refuse the command when the worker was ``busy``."""
        if busy:
            self._refuse(what, f"{busy}; {note}", "busy", counter, push_stamp)
        else:
            self._publish_diagnostics()

    def _fail(self, what: str, exc: Exception, counter: str | None) -> str:
        """A job failed (worker thread): log the traceback, count, keep it as ``last_error``;
        the worker is idle afterwards."""
        text = f"{what} failed: {type(exc).__name__}: {exc}"
        self.get_logger().error(f"{what} failed:\n{traceback.format_exc()}")
        if counter is not None:
            self.health.count(counter)
        self._problem = text[:MAX_TEXT]
        self.health.last_error = self._problem
        self._finish()
        return text

    def _finish(self, counter: str | None = None, publish: bool = True) -> None:
        """The worker's job ended (a success when ``counter`` is given)."""
        if counter is not None:
            self.health.count(counter)
            self._problem = ""
        self.worker.finish()
        if publish:
            self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        if self._closing:
            return
        busy, problem = self.worker.busy, self._problem
        time = max(self.timeline.last, 0.0)
        level = DiagnosticStatus.WARN if problem else DiagnosticStatus.OK
        message = f"busy: {busy}" if busy else "idle"
        if problem:
            message += f"; {problem}"
        values = {"state": "busy" if busy else "idle", "object": self._params.object,
                  "sim_time": f"{time:.6f}"}
        self.health.publish(level, message, values, stamp_from_seconds(time))

    # ---- executor callbacks ----------------------------------------------------------------
    def _on_clock_timer(self) -> None:
        """``/clock`` at ``clock_rate``: the physics' time while it runs (``sim_time`` is plain
        arithmetic on a step counter, safe to read while the worker steps); while the world
        rests, time passes as wall time does at every tick (:mod:`sim_bridge.resting`) and is
        published at ``idle_clock_rate``. Never goes back."""
        rested = self.rest.elapsed()
        if self._pushing:
            self.scene.clock(self.timeline.at(self._world.sim_time))
        elif self._capture is not None and not self._closing:
            now = time.monotonic()
            publish = now >= self._next_idle_clock
            if publish:
                self._next_idle_clock = now + 1.0 / self._params.idle_clock_rate
            self.rest.run(lambda: self._rest_tick(rested, publish))

    def _rest_tick(self, rested: float, publish: bool) -> None:
        """Resting time passes by ``rested`` s; ``/clock`` at the new time if ``publish``."""
        t = self.timeline.idle(rested, self._world.sim_time)
        if publish:
            self.scene.clock(t)

    def _on_idle_timer(self) -> None:
        """The camera streams while the world rests: a still frame (fresh sensor noise) with
        its pose, so a reset or restarted node gets a new observation at once."""
        if self._capture is not None and self._capture.frame is not None and not self._closing:
            self.rest.run(self._still_frame)

    def _still_frame(self) -> None:
        self._capture = self.scene.still(self._capture, self._world)
        self.scene.frame(self._capture)

    def _on_push(self, msg: Path) -> None:
        if self._arm is not None:  # the arm is driven by push_executor_node's trajectories
            self.health.count("pushes_ignored_arm_mode")
            self.health.log.warning("arm_mode", "planner/push ignored: robot is 'arm' (the "
                                    "push executor turns pushes into joint trajectories)")
            return
        stamp = msg.header.stamp
        try:
            points = push_points_from_path(msg)
        except ValueError as exc:
            self._refuse("planner/push", str(exc), "invalid", "pushes_rejected_invalid", stamp)
            return
        if not self.worker.busy and self.faults.refuse_push():
            self._refuse("planner/push", "fault injection: faults.push_refusal = "
                         f"{self.faults.config.push_refusal}", "fault", "pushes_refused_fault",
                         stamp)
            return
        busy, _ = self.worker.start("push", self._run_push, points, stamp, push=True)
        self._started(busy, "planner/push", "pushes are never queued, resend when idle",
                      "pushes_rejected_busy", stamp)

    def _on_knock(self, msg: PoseStamped) -> None:
        """``sim/knock``: displace the object at rest by (dx, dy, dyaw)."""
        try:
            check_frame(msg.header.frame_id, WORLD_FRAME)
            delta = commands.check_knock(xytheta_from_pose(msg))
        except ValueError as exc:
            self._refuse("sim/knock", str(exc), "invalid", "knocks_rejected")
            return
        busy, _ = self.worker.start("knocking the object", self._run_knock, delta)
        self._started(busy, "sim/knock", "knocks are never queued", "knocks_rejected")

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response
                  ) -> Trigger.Response:
        """Rebuild the scene from the current parameters (blocks the executor while the worker
        rebuilds: an rclpy coroutine awaiting a thread would busy-poll the executor instead)."""
        try:
            params = SimBridgeParams.from_values(parameter_values(self, PARAMETERS))
            config = params.world_config()
        except (ValueError, TypeError) as exc:
            response.success = False
            response.message = self._refuse("~/reset", f"invalid parameters: {exc}",
                                            "parameters", "resets_refused")
            return response
        self._warn(commands.unused_com_warning(parameter_values(self, PARAMETERS)))
        busy, job = self.worker.start(f"resetting to {params.object!r}", self._run_reset,
                                      config, params)
        if job is None:
            response.success = False
            response.message = self._refuse("~/reset", busy, "busy", "resets_refused")
            return response
        self._publish_diagnostics()
        response.success, response.message = job.result()  # _run_reset reports its failures
        if response.success:
            self.get_logger().info(f"~/reset: {response.message}")
        return response

    # ---- worker-thread jobs (all pybullet calls live here) ---------------------------------
    def _after_build(self) -> str:
        """Publish everything that describes a freshly built scene; return its summary."""
        capture = self.scene.capture(self._world)
        self._capture = capture
        self.scene.clock(capture.time)
        if self._arm is not None:
            self._arm.follower.hold(self._world.arm_state().positions)
            self._arm.publish_description(self._world.robot_description)
            self._arm.joint_state(float(self._world.sim_time), self._world.arm_state())
        self.scene.frame(capture)
        self.scene.camera_pose(self._world.T_world_camera, capture.time)
        return commands.scene_summary(self._world.object_spec, self._world.object_pose(),
                                      capture.info.width, capture.info.height, capture.time)

    def _run_push(self, seq: int, points: tuple[np.ndarray, np.ndarray, np.ndarray],
                  stamp: Any) -> None:
        self._pushing = True
        monitor = self._params.monitor
        try:
            result = self._world.execute_push(
                *points, monitor=monitor,
                on_frame=None if monitor is None else self.scene.monitor)
        except ValueError as exc:  # the world moved nothing (workspace, geometry of the push)
            self.worker.finish()
            kind = getattr(exc, "kind", "invalid")
            self._refuse("planner/push", str(exc), kind,
                         commands.PUSH_COUNTER.get(kind, "pushes_rejected_invalid"), stamp)
            return
        except Exception as exc:  # keep the node alive; report everything else loudly
            self._fail(f"push {seq}", exc, "pushes_failed")
            return
        finally:
            self._pushing = False
        t_start, t_end = self.timeline.at(result.t_start), self.timeline.at(result.t_end)
        executed = self.scene.executed(result.pusher_start, result.pusher_end, t_start, t_end)
        try:
            capture = self.scene.capture(self._world)
        except Exception as exc:
            self.scene.publish(self.scene.pub_executed, executed)
            self._fail(f"render after push {seq}", exc, "pushes_failed")
            return
        self._done(capture, "pushes_executed", executed)
        self.get_logger().info(commands.push_report(seq, result, t_start, t_end))
        if not getattr(result, "settled", True):
            self.get_logger().warning(f"push {seq}: the object had not come to rest when the "
                                      "settle timeout ended; the frame shows it moving")

    def _run_knock(self, delta: np.ndarray) -> None:
        """Teleport the object by ``delta``, settle, publish a fresh frame."""
        try:
            after = commands.knocked_pose(self._world.object_pose(), delta, self._world.workspace)
        except ValueError as exc:
            self.worker.finish()
            self._refuse("sim/knock", str(exc), "workspace", "knocks_rejected")
            return
        try:
            self._world.set_object_pose(after)
            capture = self.scene.capture(self._world)
        except Exception as exc:
            self._fail("knock", exc, "knocks_rejected")
            return
        self._done(capture, "knocks")
        self.get_logger().info(f"knocked the object by {np.round(delta, 4)} (m, m, rad): "
                               f"now at {np.round(self._world.object_pose(), 4)}")

    def _run_reset(self, config: WorldConfig, params: SimBridgeParams) -> tuple[bool, str]:
        time_before = self.timeline.at(self._world.sim_time)
        try:
            self._world.reset(config)
        except ValueError as exc:  # PushWorld.reset keeps the previous scene on ValueError
            self.worker.finish()
            return False, self._refuse("~/reset", f"{exc}; kept the previous scene", "scene",
                                       "resets_refused")
        except Exception as exc:
            self.timeline.new_episode(time_before)  # a rebuilt world restarts its sim_time
            try:  # never leave the node without a usable scene
                self._world.reset(self._params.world_config())
                self._after_build()
                note = "rebuilt the previous configuration"
            except Exception as exc2:
                note = f"rebuilding the previous configuration failed too: {exc2}"
            return False, f"{self._fail('reset', exc, None)}; {note}"
        # The new episode continues /clock where the old one stopped: its stamps (after its
        # initial settling) are strictly later.
        self.timeline.new_episode(time_before)
        self._params = params
        self.faults.reset(params.faults)  # no held frame of the old scene follows the new one
        try:
            summary = self._after_build()
        except Exception as exc:
            return False, self._fail("publishing the new scene", exc, None)
        self._finish("resets")
        return True, summary

    # ---- arm mode (endpoints in sim_bridge.arm_ros, physics in sim_bridge.arm_motion) -----
    def _run_arm(self) -> None:
        """Step the physics while the arm follows trajectories, then publish the tool tip path,
        a fresh frame and the ground truth (docs/design/arm.md#arm-mode-of-the-simulator)."""
        self._pushing = True
        params = self._params
        try:
            run = self._arm.run(self._world, params.arm_joint_state_rate, params.monitor,
                                self.scene.monitor, params.arm_real_time_factor)
            capture = self.scene.capture(self._world)
        except Exception as exc:  # keep the node alive; the arm holds where it is
            self._arm.follower.hold(self._world.arm_state().positions)
            self._fail("arm run", exc, "trajectory_runs_failed")
            return
        finally:
            self._pushing = False
        self._done(capture, "trajectory_runs", tool_tip=run)
        if not run.settled:
            self.get_logger().warning("arm run: the arm or the object had not come to rest "
                                      "when the settle timeout ended")

    def _done(self, capture: Capture, counter: str, executed: Path | None = None,
              tool_tip: Any = None) -> None:
        """A job succeeded: idle *before* the results go out (a client answering them at once
        must not find the bridge busy), then in order: /clock, ``sim/tool_tip``, the fresh
        frame, ground truth, ``pusher/executed``, /diagnostics (no still frame in between)."""
        with self.rest.lock:
            self._capture = capture
            self._finish(counter, publish=False)
            self.scene.clock(capture.time)
            if tool_tip is not None:
                self._arm.publish_tool_tip(tool_tip)
            self.scene.frame(capture)
            if executed is not None:
                self.scene.publish(self.scene.pub_executed, executed)
            self._publish_diagnostics()

    def _warn(self, warning: str) -> None:
        if warning:
            self.get_logger().warning(warning)

    def destroy_node(self) -> None:
        """Let a running job finish, stop the worker, then destroy the ROS entities."""
        self._closing = True
        self.worker.shutdown(self._world.close)  # queued behind a running job, if any
        super().destroy_node()


def main(args: list[str] | None = None) -> None:
    """Entry point of ``sim_bridge_node`` (``ros2 run`` / ``pushbot run``)."""
    run_node(SimBridgeNode, NODE_NAME, args)


if __name__ == "__main__":
    main()
