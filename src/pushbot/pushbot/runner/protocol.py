"""The source's evaluation protocol (Kloss et al. 2020, thesis ch. 5;
docs/design/evaluation.md) as data: tasks, goal regions, methods and trials.

One :class:`Trial` is one episode: an object at the workspace centre with an initial
orientation, a goal relative to the initial pose, a method, a state source and the physics
seed. The in-process evaluation (``pushbot eval``), the ROS-graph runs (``--graph``) and the
demo all build their episodes from it, so the same trial means the same scene, goal and planner
seed everywhere.

Definitions (docs/design/evaluation.md):

- Tasks: ``translation`` moves 20 cm and keeps the orientation, ``rotation`` turns by
  0.5 rad and keeps the position, ``mixed`` moves 10 cm and turns by 0.35 rad. The direction of
  the translation is uniform over the circle and the sign of the rotation is +-1 with equal
  probability, both drawn from the trial's seed.
- Trials: index ``i`` in ``0 .. n-1``; the initial orientation is ``2 pi (i mod 20) / 20``
  (20 steps over 0-360 deg), ``i // 20`` is the run; 60 trials = 20 orientations x 3 runs.
- Goals are relative to the initial pose: position in ``world``, orientation as a rotation since
  the start. That is the frame the perception reports yaw in (its first frame has yaw 0), so
  the same offset applies to ground truth and to the perceived pose.
- Goal regions: ``small`` 0.75 cm / 5 deg (the default success criterion),
  ``medium`` 2.5 cm / 7.5 deg, ``large`` 5 cm / 10 deg.
- Physics: every trial randomises mass and frictions from its seed (``WorldConfig.randomize``);
  ``com="centre"`` overrides the COM with the geometric centre, ``com="random"`` keeps the
  randomised COM (uniform over the outline shrunk by 30 %), ``com="spec"`` overrides it with the
  object specification's ``com_offset`` (objects whose COM is part of their definition, such as
  the shape benchmark's ``com_edge`` class; mass and frictions stay randomised).
- Methods: ``ana``, ``lrn``, ``geo``, ``rdn`` (planner contact selection), ``ana-direct``,
  ``lrn-direct`` (affordances with linear length rescaling instead of rollouts) and
  ``pushnet`` (the Push-Net-style sampling baseline).
- State sources: ``gt`` (true pose, COM, friction; ``l`` from the uniform-pressure guess) or
  ``filter`` (rendered RGB-D -> segmentation -> EKF). ``estimate_com = False`` (``filter``
  only) pins the EKF's COM at the geometric centre: the "without COM estimation" rows of the
  source's Table 5.2.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "COM_MODES",
    "METHODS",
    "REGIONS",
    "STATE_SOURCES",
    "TASKS",
    "Trial",
    "bridge_scene_params",
    "check_graph_trial",
    "make_trials",
    "planner_episode_params",
]

#: task -> (translation distance m, rotation magnitude rad)
TASKS: dict[str, tuple[float, float]] = {
    "translation": (0.20, 0.0),
    "rotation": (0.0, 0.5),
    "mixed": (0.10, 0.35),
}

#: goal region -> (position tolerance m, orientation tolerance rad)
REGIONS: dict[str, tuple[float, float]] = {
    "small": (0.0075, math.radians(5.0)),
    "medium": (0.025, math.radians(7.5)),
    "large": (0.05, math.radians(10.0)),
}

#: method -> (planner method or "pushnet", direct)
METHODS: dict[str, tuple[str, bool]] = {
    "ana": ("ana", False),
    "lrn": ("lrn", False),
    "geo": ("geo", False),
    "rdn": ("rdn", False),
    "ana-direct": ("ana", True),
    "lrn-direct": ("lrn", True),
    "pushnet": ("pushnet", False),
}

STATE_SOURCES = ("gt", "filter")
COM_MODES = ("centre", "random", "spec")

#: initial orientations per run (the source's protocol: 20 steps over 0-360 deg)
ORIENTATIONS = 20


def _check(name: str, value: str, allowed: Any) -> None:
    if value not in allowed:
        raise ValueError(f"{name} must be one of {', '.join(sorted(allowed))}, got {value!r}")


@dataclass(frozen=True)
class Trial:
    """One episode of the protocol (module docstring).

    Attributes
    ----------
    object : str
        Library object name or object specification file path.
    task : str
        ``translation`` | ``rotation`` | ``mixed``.
    method : str
        A key of :data:`METHODS`.
    k : int
        Contact points sampled per step (ignored by ``pushnet``).
    state : str
        ``gt`` | ``filter``.
    com : str
        ``centre`` | ``random`` | ``spec`` (module docstring).
    region : str
        ``small`` | ``medium`` | ``large``.
    index : int
        Trial index, >= 0 (orientation ``index mod 20``, run ``index // 20``).
    seed : int
        Base seed of the evaluation, >= 0.
    max_steps : int
        Pushes allowed (30).
    estimate_com : bool
        ``filter``: the EKF estimates the COM (True) or keeps it at the geometric centre.
        Ignored by ``gt``.
    horizon : int
        Pushes the planner looks ahead (``PlannerConfig.horizon``; 1 = greedy, the
        source's planner). Ignored by ``pushnet``.
    avoid_contradicted : bool
        The planner avoids the contact region of a push whose observed outcome contradicted
        its prediction (``PlannerConfig.avoid_contradicted``). Ignored by ``pushnet``.
    relearn : bool
        ``filter``: the EKF restarts COM, limit surface and friction at their priors when the
        pushes contradict the model (``EKFConfig.relearn``). Ignored by ``gt``.
    support_cell : float
        The simulated object's support (``sim_bridge.world.WorldConfig.support_cell``): 0 =
        its convex pieces whole (resting on 3-4 corners each), > 0 = cut into cells of this
        size, m, supported across the footprint.

    The three planner and filter variants and the support do not enter :attr:`trial_seed`:
    every variant faces the same scenes and goals.
    """

    object: str
    task: str = "mixed"
    method: str = "ana"
    k: int = 3
    state: str = "gt"
    com: str = "centre"
    region: str = "small"
    index: int = 0
    seed: int = 0
    max_steps: int = 30
    estimate_com: bool = True
    horizon: int = 1
    avoid_contradicted: bool = False
    relearn: bool = False
    support_cell: float = 0.0

    def __post_init__(self) -> None:
        _check("task", self.task, TASKS)
        _check("method", self.method, METHODS)
        _check("state", self.state, STATE_SOURCES)
        _check("com", self.com, COM_MODES)
        _check("region", self.region, REGIONS)
        if int(self.k) < 1:
            raise ValueError(f"k must be >= 1, got {self.k}")
        if int(self.index) < 0 or int(self.seed) < 0:
            raise ValueError(f"index and seed must be >= 0, got {self.index}, {self.seed}")
        if int(self.max_steps) < 1:
            raise ValueError(f"max_steps must be >= 1, got {self.max_steps}")
        if isinstance(self.horizon, bool) or not isinstance(self.horizon, int | np.integer) \
                or self.horizon < 1:
            raise ValueError(f"horizon must be an integer >= 1, got {self.horizon!r}")
        object.__setattr__(self, "horizon", int(self.horizon))
        if not (isinstance(self.support_cell, float) and self.support_cell == 0.0):
            from sim_bridge.config import check_support_cell  # the simulator's rule

            object.__setattr__(self, "support_cell", check_support_cell(self.support_cell))
        for name in ("estimate_com", "avoid_contradicted", "relearn"):
            value = getattr(self, name)
            if not isinstance(value, bool | np.bool_):
                raise ValueError(f"{name} must be a bool, got {value!r}")
            object.__setattr__(self, name, bool(value))

    # -- derived quantities -------------------------------------------------------------------
    @property
    def object_name(self) -> str:
        """The object's short name (the file stem for a specification file)."""
        return Path(self.object).stem if Path(self.object).suffix else self.object

    @property
    def trial_seed(self) -> int:
        """Seed of everything random in this trial (physics, goal, planner), stable across
        Python processes (``zlib.crc32``, not ``hash``) and independent of the method and state
        source, so different methods face the same scenes and goals."""
        key = f"{self.object_name}|{self.task}|{self.com}|{self.index}".encode()
        return int(np.random.SeedSequence([int(self.seed), zlib.crc32(key)])
                   .generate_state(1)[0])

    @property
    def initial_yaw(self) -> float:
        """Initial orientation of the object in ``world``, radians."""
        return 2.0 * math.pi * (self.index % ORIENTATIONS) / ORIENTATIONS

    @property
    def tolerances(self) -> tuple[float, float]:
        """(position m, orientation rad) of the goal region."""
        return REGIONS[self.region]

    def goal_offset(self) -> NDArray[np.float64]:
        """(dx, dy, dtheta): goal minus initial pose (position in ``world``, rotation since the
        start), drawn from :attr:`trial_seed`."""
        distance, rotation = TASKS[self.task]
        rng = np.random.default_rng([self.trial_seed, 1])
        direction = rng.uniform(0.0, 2.0 * math.pi)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        return np.array([distance * math.cos(direction), distance * math.sin(direction),
                         sign * rotation])

    def goal(self, initial_pose: NDArray[np.float64] | Any) -> NDArray[np.float64]:
        """The goal pose for an episode that starts at ``initial_pose`` (x, y, theta)."""
        return np.asarray(initial_pose, dtype=np.float64)[:3] + self.goal_offset()

    @property
    def planner_method(self) -> str:
        return METHODS[self.method][0]

    @property
    def direct(self) -> bool:
        return METHODS[self.method][1]

    @property
    def planner_seed(self) -> int:
        return int(np.random.default_rng([self.trial_seed, 2]).integers(0, 2**31 - 1))

    def world_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``sim_bridge.world.WorldConfig`` for this trial (the caller adds
        camera and rendering options)."""
        kwargs: dict[str, Any] = {
            "object": self.object,
            "object_pose": (0.0, 0.0, self.initial_yaw),
            "randomize": True,
            "seed": int(self.trial_seed % (2**31 - 1)),
            "support_cell": self.support_cell,
        }
        if self.com == "centre":
            kwargs["com_offset"] = (0.0, 0.0)
        elif self.com == "spec":
            from push_core.objects import load_object

            kwargs["com_offset"] = tuple(float(v) for v in load_object(self.object).com)
        return kwargs

    def planner_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of ``push_core.planner.PlannerConfig`` (not for ``pushnet``)."""
        tol_xy, tol_theta = self.tolerances
        return {"method": self.planner_method, "direct": self.direct, "k": int(self.k),
                "tolerance_xy": tol_xy, "tolerance_theta": tol_theta,
                "seed": self.planner_seed, "horizon": self.horizon,
                "avoid_contradicted": self.avoid_contradicted}

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def make_trials(objects: list[str], tasks: list[str], methods: list[str], ks: list[int],
                n: int, *, state: str = "gt", com: str = "centre", region: str = "small",
                seed: int = 0, max_steps: int = 30, estimate_com: bool = True,
                horizon: int = 1, avoid_contradicted: bool = False, relearn: bool = False,
                support_cell: float = 0.0) -> list[Trial]:
    """The cross product objects x tasks x methods x ks x ``n`` trial indices, in that order."""
    if n < 1:
        raise ValueError(f"the number of trials must be >= 1, got {n}")
    return [Trial(object=o, task=t, method=mth, k=k, state=state, com=com, region=region,
                  index=i, seed=seed, max_steps=max_steps, estimate_com=estimate_com,
                  horizon=horizon, avoid_contradicted=avoid_contradicted, relearn=relearn,
                  support_cell=support_cell)
            for o in objects for t in tasks for mth in methods for k in ks for i in range(n)]


def planner_episode_params(trial: Trial) -> dict[str, Any]:
    """``planner_node``'s episode parameters for ``trial`` (set before every episode; also
    the start-up parameters of a planner restarted mid-episode)."""
    kw = trial.planner_kwargs()
    return {"method": kw["method"], "direct": bool(kw["direct"]), "k": int(kw["k"]),
            "goal_tolerance.xy": float(kw["tolerance_xy"]),
            "goal_tolerance.theta": float(kw["tolerance_theta"]),
            "max_steps": int(trial.max_steps), "seed": int(kw["seed"]),
            "lookahead.horizon": int(kw["horizon"]),
            "avoid_contradicted": bool(kw["avoid_contradicted"])}


def bridge_scene_params(trial: Trial) -> dict[str, Any]:
    """``sim_bridge_node``'s scene parameters of ``trial`` (object, initial pose, COM, seed,
    randomisation, support), set before every graph episode (also the start-up parameters of a
    simulator restarted mid-episode)."""
    world = trial.world_kwargs()
    x, y, theta = world["object_pose"]
    com = world.get("com_offset")
    return {"object": str(world["object"]), "initial_pose.x": float(x),
            "initial_pose.y": float(y), "initial_pose.theta": math.remainder(theta, 2 * math.pi),
            "use_com_offset": com is not None,
            "com_offset": [0.0, 0.0] if com is None else [float(v) for v in com],
            "seed": int(world["seed"]), "randomize": bool(world["randomize"]),
            "support_cell": float(world["support_cell"])}


def check_graph_trial(trial: Trial) -> None:
    """``ValueError`` for trials the ROS graph cannot run (:mod:`pushbot.runner.episode`): it
    estimates the state from images, has no Push-Net node and no COM pinning."""
    if not isinstance(trial, Trial):
        raise ValueError(f"expected a pushbot.runner.protocol.Trial, "
                         f"got {type(trial).__name__}")
    if trial.state != "filter":
        raise ValueError(f"the graph estimates the state from images: state must be 'filter', "
                         f"got {trial.state!r}")
    if trial.method == "pushnet":
        raise ValueError("the graph has no Push-Net node: method 'pushnet' runs in-process only")
    if not getattr(trial, "estimate_com", True):
        raise ValueError("estimate_com=False (COM pinned) is not available in the graph")
