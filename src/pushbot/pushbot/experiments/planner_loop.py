"""In-process closed loop of the planner with ground-truth state: no ROS, no perception, no EKF.

The acceptance test (``tests/planner/test_closed_loop.py``) and the planner benchmark
(``benchmarks/bench_planner.py``) run episodes with it: at every step the planner gets the
*true* state of the simulated object and one push is executed in the pybullet world
(``sim_bridge.world.PushWorld``, passed in; this module does not import it).

Ground-truth state: the pose from ``world.object_pose()``, the simulated COM
(``world.object_spec.com``) and pusher friction (``world.object_spec.friction_pusher``), and
``l = spec.limit_surface_guess()`` (uniform pressure): a physics engine has no limit-surface
parameter to read, so the analytical model's own value for the simulated shape is used. The
outline is the library shape sampled every ``outline_spacing`` metres with its outward normals
(object frame), what perception delivers.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.episode import EpisodeEngine
from push_core.planner import Outline, Planner, prepare_outline

__all__ = ["EpisodeResult", "ground_truth_state", "run_episode", "translation_goal"]


@dataclass
class EpisodeResult:
    """Outcome of one episode.

    Attributes
    ----------
    success : bool
        The object was within the goal tolerances after at most ``max_steps`` pushes.
    steps : int
        Pushes executed (including refused ones, which count as steps).
    final_error_xy : float
        Position error at the end, metres.
    final_error_theta : float
        Absolute orientation error at the end, radians.
    refused : int
        Planned pushes the world refused (``ValueError``); nothing moved, and the next plans
        avoid their contact region until a push is executed (``Planner.plan(avoid=...)``).
    planning_ms : list of float
        Wall time of every planning call, milliseconds.
    poses : list of ndarray
        Object pose before the first push and after every push.
    """

    success: bool
    steps: int
    final_error_xy: float
    final_error_theta: float
    refused: int = 0
    planning_ms: list[float] = field(default_factory=list)
    poses: list[NDArray[np.float64]] = field(default_factory=list)


def ground_truth_state(world: Any) -> NDArray[np.float64]:
    """The 7-vector ``(x, y, theta, c_x, c_y, l, m)`` of the simulated object (module docstring).

    Parameters
    ----------
    world : sim_bridge.world.PushWorld
    """
    spec = world.object_spec
    return np.array([*world.object_pose(), *spec.com, spec.limit_surface_guess(),
                     spec.friction_pusher])


def translation_goal(pose: ArrayLike, distance: float, direction: float) -> NDArray[np.float64]:
    """Goal of a translation task: move ``distance`` metres along ``direction`` (radians, in
    ``world``), keep the orientation."""
    x, y, theta = np.asarray(pose, dtype=np.float64)
    return np.array([x + distance * math.cos(direction), y + distance * math.sin(direction),
                     theta])


def run_episode(world: Any, planner: Planner, goal: ArrayLike, max_steps: int = 30,
                outline: Outline | None = None, outline_spacing: float = 0.002) -> EpisodeResult:
    """Push the world's object towards ``goal`` until it is reached or ``max_steps`` pushes ran.

    Parameters
    ----------
    world : sim_bridge.world.PushWorld
        The simulated scene, object at its start pose.
    planner : Planner
        Its tolerances decide success.
    goal : array_like, shape (3,)
        Goal pose in ``world``.
    max_steps : int
        Largest number of pushes.
    outline : Outline, optional
        Default: the simulated shape sampled every ``outline_spacing`` metres.
    outline_spacing : float
        Metres.

    Returns
    -------
    EpisodeResult
    """
    goal = np.asarray(goal, dtype=np.float64)
    spec = world.object_spec
    if outline is None:
        outline = prepare_outline(*spec.outline(outline_spacing),
                                  simplify_tolerance=planner.config.simplify_tolerance)
    base = ground_truth_state(world)
    engine = EpisodeEngine(planner, max_steps)
    engine.new_goal(goal)
    engine.set_outline(outline)
    result = EpisodeResult(success=False, steps=0, final_error_xy=math.inf,
                           final_error_theta=math.inf)
    while True:
        pose = world.object_pose()
        result.poses.append(pose)
        err = goal - pose
        result.final_error_xy = float(math.hypot(err[0], err[1]))
        result.final_error_theta = abs(float(np.angle(np.exp(1j * err[2]))))
        state = base.copy()
        state[:3] = pose
        engine.estimate(world.sim_time, state)
        t0 = time.perf_counter()
        step = engine.step()
        if step.action == "reached":
            result.success = True
            break
        if step.action != "push":  # max steps or no feasible push
            break
        plan = step.plan
        result.planning_ms.append(1e3 * (time.perf_counter() - t0))
        result.steps = engine.steps
        try:
            world.execute_push(plan.approach, plan.contact, plan.end)
            engine.push_executed(world.sim_time)
        except ValueError:  # nothing moved: its contact region is avoided (the engine)
            result.refused += 1
            engine.push_lost()
    return result
