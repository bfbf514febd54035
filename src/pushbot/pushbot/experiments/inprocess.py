"""One protocol trial in-process: the nodes' cores without DDS (``pushbot eval``).

:func:`run_trial` builds the scene of a :class:`pushbot.runner.protocol.Trial` in the pybullet
world (``sim_bridge.world.PushWorld``), runs the closed loop and returns the *episode record* of
docs/design/evaluation.md. Each cycle:

1. **State.** ``gt``: the true pose, the simulated COM and pusher friction and
   ``l = spec.limit_surface_guess()``; the outline is the
   library shape sampled every 2 mm. ``filter``: a 640 x 480 RGB-D frame rendered after every
   push goes through the segmentation CNN (``push_perception.model.Segmenter``) and the
   mask-to-state core (``push_perception.tracker.EpisodeTracker``: position, orientation relative
   to the first frame, outline from the first frame); ``push_core.estimator.PushEKF`` is
   predicted with the executed pusher motion and updated with the perceived pose and its
   covariance, as ``ekf_node`` does. A frame without a pose (``PerceptionError``) leaves the
   prediction alone. ``estimate_com = False`` pins the COM at the geometric centre (prior and
   random walk of the COM zero), the "without COM estimation" rows of the source's Table 5.2;
   ``relearn = True`` turns on the filter's re-learning (``EKFConfig.relearn``).
2. **Goal** in the frame of the state source: ``trial.goal(first pose)`` (for ``filter`` the
   first perceived pose, yaw 0 at the first frame; for ``gt`` the true initial pose).
3. **Stop** by the stop rule (``Planner.reached``: the *state source's* pose within the
   region shrunk by its uncertainty, ``push_core.planner.goal_reached``; as ``planner_node``:
   the robot only knows its estimate; ``gt`` has no uncertainty) or after ``max_steps``
   pushes. A continuously symmetric outline (a disc) is stopped and scored on the position
   alone.
4. **Plan** with ``push_core.planner.Planner`` (``Trial.planner_kwargs``) or, for ``pushnet``,
   ``push_core.pushnet.PushNetPlanner``; execute in the world. A push the world refuses
   (``ValueError``) counts as a step and moves nothing; until a push is executed, the planner
   avoids the outline points of the refused pushes (``Planner.plan(avoid=...)``; the
   ``pushnet`` baseline draws new random pushes anyway).

Success and end errors always come from ground truth (:func:`end_score`): the true pose
against the true initial pose plus ``trial.goal_offset()``; the orientation error is taken
modulo the object's rotational symmetry (``2 pi / k`` for a k-fold symmetric outline, e.g. hex
k = 6) and not counted for a continuously symmetric one (``orientation_ignored``).

``poses_est`` are in the state source's frame (``filter``: yaw since the first frame, world
axes at that frame; add the true initial yaw to compare with ``poses_true``). ``com_error``
compares the EKF's COM (its object frame) with the true COM turned into that frame, allowing for
a symmetric object's orientation having been re-initialised to an equivalent one.

Expensive objects (the pybullet world, the segmentation network, the learned affordance model)
are cached per process by :class:`EpisodeRunner`; :func:`run_trial` uses one runner per process.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.episode import EpisodeEngine, end_score, new_record, robot_times, true_errors
from push_core.estimator import EKFConfig, PushEKF
from push_core.geometry import rot2, wrap_angle
from push_core.planner import Planner, PlannerConfig, prepare_outline
from push_core.pushnet import PushNetConfig, PushNetPlanner
from push_core.symmetry import symmetry_order_of_polygon
from pushbot.runner.protocol import Trial

__all__ = ["EpisodeRunner", "end_score", "run_trial", "true_errors"]

#: Outline sampling of the ground-truth state source, metres (what perception delivers).
GT_OUTLINE_SPACING = 0.002
#: COM prior scale of the EKF when the COM is not estimated (> 0 is required; this pins it).
PINNED_COM_PRIOR = 1e-9


class EpisodeRunner:
    """Runs trials in this process, caching the world and the networks between trials.

    Parameters
    ----------
    segmentation_weights : str, optional
        Segmentation network weights (default: the bundled ones), for ``filter``.
    lrn_weights : str, optional
        Learned affordance weights (default: the bundled ones), for ``lrn`` methods.
    ekf_config : EKFConfig, optional
        Filter settings (default: ``EKFConfig()``, the node's defaults).
    """

    def __init__(self, segmentation_weights: str | None = None, lrn_weights: str | None = None,
                 ekf_config: EKFConfig | None = None) -> None:
        self.segmentation_weights = segmentation_weights
        self.lrn_weights = lrn_weights
        self.ekf_config = EKFConfig() if ekf_config is None else ekf_config
        self._world: Any = None
        self._segmenter: Any = None
        self._lrn: Any = None

    # -- cached resources -----------------------------------------------------------------------
    def _make_world(self, trial: Trial, camera_pose: Any = None) -> Any:
        from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout

        cfg = WorldConfig(**trial.world_kwargs(), **(
            {} if camera_pose is None else {"camera_pose": tuple(camera_pose)}))
        with quiet_stdout():  # pybullet prints "argv[0]=" when it connects
            if self._world is None:
                self._world = PushWorld(cfg)
            else:
                self._world.reset(cfg)
        return self._world

    def segmenter(self) -> Any:
        if self._segmenter is None:
            from push_perception.model import Segmenter

            self._segmenter = Segmenter.load(self.segmentation_weights or None)
        return self._segmenter

    def learned_model(self) -> Any:
        if self._lrn is None:
            from push_core.learned import load_affordance_model
            from push_planner.models import default_weights

            self._lrn = load_affordance_model(self.lrn_weights or str(default_weights()))
        return self._lrn

    def close(self) -> None:
        if self._world is not None:
            self._world.close()
            self._world = None

    # -- one trial ------------------------------------------------------------------------------
    def _planner(self, trial: Trial, world: Any) -> Planner | PushNetPlanner:
        tol_xy, tol_theta = trial.tolerances
        radius = world.config.pusher_radius
        if trial.method == "pushnet":
            return PushNetPlanner(PushNetConfig(
                tolerance_xy=tol_xy, tolerance_theta=tol_theta, pusher_radius=radius,
                workspace=world.workspace, seed=trial.planner_seed,
                max_push_length=world.config.max_push_length))
        model = self.learned_model() if trial.planner_method == "lrn" else None
        return Planner(PlannerConfig(**trial.planner_kwargs(), pusher_radius=radius,
                                     workspace=world.workspace), model)

    def run(self, trial: Trial, camera_pose: Any = None, extrinsics: Any = None
            ) -> dict[str, Any]:
        """Run one trial; returns the episode record (module docstring,
        docs/design/evaluation.md#episode-record). ``camera_pose`` (x, y, z, qx, qy, qz, qw)
        places the camera (``WorldConfig.camera_pose``); ``extrinsics`` (4, 4), the
        ``T_world_camera`` perception uses instead of the true one (a calibration's)."""
        if not isinstance(trial, Trial):
            raise ValueError(f"trial: expected a pushbot.runner.protocol.Trial, got "
                             f"{type(trial).__name__}")
        t_start = time.perf_counter()
        world = self._make_world(trial, camera_pose)
        spec = world.object_spec
        order = symmetry_order_of_polygon(spec.polyline())
        pose0_true = world.object_pose()
        goal_true = pose0_true + trial.goal_offset()
        rec = new_record(trial.as_dict(), perception_failures=0, poses_predicted=[])
        source = _GroundTruth(world) if trial.state == "gt" else _Filter(
            world, self.segmenter(), self._ekf_config(trial), extrinsics)
        try:
            state = source.first()
        except _NoPose as exc:
            rec["reason"] = f"perception failed on the first frame: {exc}"
            return self._finish(rec, world, goal_true, t_start)
        goal = trial.goal(state[:3])
        planner = self._planner(trial, world)
        outline = source.outline(planner)
        rec["orientation_used"] = bool(outline.orientation_matters)  # the system's view
        rec["poses_true"].append(pose0_true.tolist())
        rec["poses_est"].append(state[:3].tolist())
        engine = EpisodeEngine(planner, trial.max_steps)
        engine.new_goal(goal)
        t_goal, commands = world.sim_time, []
        engine.set_outline(outline)
        engine.estimate(world.sim_time, state, source.covariance())
        while True:
            t0 = time.perf_counter()
            step = engine.step()
            if step.action != "push":
                if step.action in ("wait", "refused"):  # cannot happen in this loop
                    raise RuntimeError(f"episode engine: {step.action} {step.reason}")
                rec["reason"] = "goal reached" if step.action == "reached" else engine.failure
                break
            plan = step.plan
            rec["planning_ms"].append(1e3 * (time.perf_counter() - t0))
            rec["steps"] = engine.steps
            rec["pushes"].append([plan.approach.tolist(), plan.contact.tolist(),
                                  plan.end.tolist()])
            rec["poses_predicted"].append(np.asarray(plan.predicted_pose).tolist())
            commands.append(world.sim_time)
            try:
                result = world.execute_push(plan.approach, plan.contact, plan.end)
                engine.push_executed(world.sim_time)
            except ValueError:  # refused, nothing moved: its contact region is avoided
                rec["refused"] += 1
                result = None
                engine.push_lost()
            state = source.after(result)
            engine.estimate(world.sim_time, state, source.covariance())
            rec["poses_true"].append(world.object_pose().tolist())
            rec["poses_est"].append(state[:3].tolist())
        rec["perception_failures"] = source.failures
        rec["com_error"] = source.com_error(pose0_true[2], order)
        rec.update(robot_times(t_goal, commands, world.sim_time))
        return self._finish(rec, world, goal_true, t_start)

    def _ekf_config(self, trial: Trial) -> EKFConfig:
        config = replace(self.ekf_config, relearn=True) if trial.relearn else self.ekf_config
        if trial.estimate_com:
            return config
        return replace(config, com_prior_fraction=PINNED_COM_PRIOR, com_noise=0.0)

    @staticmethod
    def _finish(rec: dict[str, Any], world: Any, goal_true: NDArray[np.float64],
                t_start: float) -> dict[str, Any]:
        rec.update(end_score(world.object_spec.polyline(), world.object_pose(), goal_true,
                             Trial(**rec["trial"]).tolerances))
        rec["wall_s"] = time.perf_counter() - t_start
        return rec


class _NoPose(RuntimeError):
    pass


class _GroundTruth:
    """The ``gt`` state source."""

    failures = 0

    def __init__(self, world: Any) -> None:
        self.world = world
        spec = world.object_spec
        self.base = np.array([0.0, 0.0, 0.0, *spec.com, spec.limit_surface_guess(),
                              spec.friction_pusher])

    def _state(self) -> NDArray[np.float64]:
        s = self.base.copy()
        s[:3] = self.world.object_pose()
        return s

    def first(self) -> NDArray[np.float64]:
        return self._state()

    def outline(self, planner: Planner | PushNetPlanner) -> Any:
        return prepare_outline(*self.world.object_spec.outline(GT_OUTLINE_SPACING),
                               simplify_tolerance=planner.config.simplify_tolerance)

    def after(self, result: Any) -> NDArray[np.float64]:
        return self._state()

    def covariance(self) -> NDArray[np.float64] | None:
        return None  # the exact state

    def com_error(self, theta0: float, order: int) -> float | None:
        return None


class _Filter:
    """The ``filter`` state source: rendered frames -> segmentation -> EKF."""

    def __init__(self, world: Any, segmenter: Any, config: EKFConfig,
                 extrinsics: Any = None) -> None:
        from push_perception.tracker import EpisodeTracker

        self.world, self.extrinsics = world, extrinsics
        self.segmenter = segmenter
        self.config = replace(config, pusher_radius=world.config.pusher_radius)
        self.tracker = EpisodeTracker()
        self.ekf: PushEKF | None = None
        self.failures = 0

    def _measure(self) -> Any:
        from push_perception.perception_config import PerceptionError

        try:
            frame = self.world.render()
            if self.extrinsics is not None:
                frame = replace(frame, T_world_camera=np.asarray(self.extrinsics, dtype=float))
            return self.tracker.measure_frame(self.segmenter, frame)
        except PerceptionError as exc:
            self.failures += 1
            raise _NoPose(f"{exc.kind}: {exc}") from None

    def first(self) -> NDArray[np.float64]:
        meas = self._measure()
        points, normals = self.tracker.outline
        self.ekf = PushEKF(points, normals, self.config)
        self.ekf.update_pose(meas.pose, meas.covariance)
        return self.ekf.state

    def outline(self, planner: Planner | PushNetPlanner) -> Any:
        points, normals = self.tracker.outline
        return prepare_outline(points, normals,
                               simplify_tolerance=planner.config.simplify_tolerance)

    def after(self, result: Any) -> NDArray[np.float64]:
        assert self.ekf is not None
        if result is not None:
            self.ekf.predict_push(result.pusher_start, result.pusher_end)
        try:
            meas = self._measure()
        except _NoPose:
            return self.ekf.state
        self.ekf.update_pose(meas.pose, meas.covariance)
        return self.ekf.state

    def covariance(self) -> NDArray[np.float64] | None:
        assert self.ekf is not None
        return self.ekf.covariance

    def com_error(self, theta0: float, order: int) -> float | None:
        """|c_est - c_true| in the EKF's frame (module docstring), metres."""
        if self.ekf is None:
            return None
        x = self.ekf.state
        theta_true = self.world.object_pose()[2]
        relative_true = theta_true - theta0  # the perception frame's yaw since the start
        period = self.ekf.period
        shift = period * round(float(wrap_angle(x[2] - relative_true)) / period)
        c_true = rot2(theta0 - shift) @ np.asarray(self.world.object_spec.com, dtype=float)
        return float(math.hypot(*(x[3:5] - c_true)))


_RUNNER: EpisodeRunner | None = None
_RUNNER_KEY: tuple = ()


def run_trial(trial: Trial, camera_pose: Any = None, extrinsics: Any = None,
              **options: Any) -> dict[str, Any]:
    """Run one trial in this process and return its episode record.

    Parameters
    ----------
    trial : Trial
    **options
        ``segmentation_weights``, ``lrn_weights`` (paths, "" = bundled) and ``ekf_config``
        (:class:`push_core.estimator.EKFConfig`) of :class:`EpisodeRunner`. A process keeps one
        runner (world and networks cached) per set of options.
    camera_pose, extrinsics
        As :meth:`EpisodeRunner.run`.
    """
    global _RUNNER, _RUNNER_KEY
    key = tuple(sorted(options.items()))
    if _RUNNER is None or key != _RUNNER_KEY:
        if _RUNNER is not None:
            _RUNNER.close()
        _RUNNER, _RUNNER_KEY = EpisodeRunner(**options), key
    return _RUNNER.run(trial, camera_pose, extrinsics)
