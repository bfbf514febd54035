"""``pushbot eval push``: the source's closed-loop experiments, in-process.

Every combination of the list options (objects x tasks x methods x k x state x com x region x
COM estimation) is a *cell*; each cell runs ``--trials`` trials of
:mod:`pushbot.runner.protocol` (index i: initial orientation 2 pi (i mod 20) / 20, run i // 20;
physics, goal and planner seeds from ``--seed``). Trials run in worker processes (``--workers``,
default: the usable cores; ``forkserver`` start method, one torch/OpenCV thread each) with the same
cores as the nodes (:mod:`pushbot.experiments.inprocess`), on a Ray cluster (``--ray ADDRESS``,
``local`` starts one; needs the optional extra ``pip install 'pushbot[ray]'``) or through the real
ROS graph (``--graph``, :mod:`pushbot.runner.episode`). ``pushnet`` ignores ``k`` (its cells use the
first value); ``gt`` ignores the COM estimation switch (its cells use ``on``).

Output in ``--out`` (default ``out/eval``):

- ``results.json``: ``config`` (the options), ``cells`` (one record per cell: the cell's
  options, ``n``, ``success_rate``, ``steps_mean`` / ``steps_std`` over the successful
  trials, true end errors ``end_error_xy_*`` (m) / ``end_error_theta_*`` (rad) mean and std over
  all trials, ``com_error_*`` (m, ``filter``), ``reasons``, and ``timing`` with the
  planning-time median and the mean episode wall time), ``trials`` (the episode records of
  docs/design/evaluation.md#episode-record, in trial order) and ``timing`` (total wall time,
  workers, load).
  Wall times are only in ``timing`` keys and the records' ``wall_s`` / ``planning_ms``; the rest
  is a deterministic function of the options
  (:func:`pushbot.experiments.eval_report.deterministic_view`), so the same seed
  gives the same JSON.
- ``fig5_5.png`` (success and steps vs k for ana, lrn, geo, rdn per task), ``fig5_6.png``
  (direct variants vs rollouts), ``fig5_7.png`` (success and steps vs goal region, ana vs
  pushnet): drawn when the cells hold the methods they compare.
- ``tables.md``: Tables 5.1 (mixed task, ana, COM centre: gt vs filter) and 5.2 (mixed task,
  random COM, filter: ana / lrn with and without COM estimation per object) next to the
  source's numbers, when the cells hold them.

Examples::

    pushbot eval push --objects tri1 butter hex --tasks mixed --state gt filter --trials 60
    pushbot eval push --tasks mixed --com random --state filter --methods ana lrn \\
        --com-estimation off on
    pushbot eval push --methods ana geo rdn lrn --k 1 3 10 --trials 20
    pushbot eval push --methods ana pushnet --region small medium large
    pushbot eval push --state filter --horizon 2 --avoid-contradicted --relearn
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.experiments.eval_report import cells_markdown, summarise, write_outputs
from pushbot.runner.protocol import COM_MODES, METHODS, REGIONS, STATE_SOURCES, TASKS, Trial

__all__ = [
    "DEFAULT_OBJECTS",
    "EvalOptions",
    "add_arguments",
    "build_trials",
    "evaluate",
    "options_from_args",
    "run",
    "usable_cores",
]

DEFAULT_OBJECTS = ("tri1", "butter", "hex")


# --------------------------------------------------------------------------------------------
# Options and trials
# --------------------------------------------------------------------------------------------
class EvalOptions:
    """The validated options of one evaluation (the command line's, as attributes)."""

    def __init__(self, *, objects: Sequence[str] = DEFAULT_OBJECTS,
                 tasks: Sequence[str] = tuple(TASKS), methods: Sequence[str] = ("ana",),
                 k: Sequence[int] = (3,), state: Sequence[str] = ("gt",),
                 com: Sequence[str] = ("centre",), region: Sequence[str] = ("small",),
                 com_estimation: Sequence[str] = ("on",), trials: int = 60, seed: int = 0,
                 max_steps: int = 30, horizon: int = 1, avoid_contradicted: bool = False,
                 relearn: bool = False, support_cell: float = 0.0) -> None:
        def listed(name: str, values: Sequence[Any], allowed: Iterable[Any] | None) -> list[Any]:
            values = list(dict.fromkeys(values))  # unique, in order
            if not values:
                raise ValueError(f"--{name.replace('_', '-')}: give at least one value")
            if allowed is not None:
                allowed = list(allowed)
                bad = [v for v in values if v not in allowed]
                if bad:
                    raise ValueError(f"--{name.replace('_', '-')}: unknown value(s) "
                                     f"{', '.join(map(str, bad))}; choose from "
                                     f"{', '.join(map(str, allowed))}")
            return values

        self.objects = listed("objects", objects, None)
        self.tasks = listed("tasks", tasks, TASKS)
        self.methods = listed("methods", methods, METHODS)
        self.k = listed("k", k, None)
        self.state = listed("state", state, STATE_SOURCES)
        self.com = listed("com", com, COM_MODES)
        self.region = listed("region", region, REGIONS)
        self.com_estimation = listed("com_estimation", com_estimation, ("on", "off"))
        for v in self.k:
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 1:
                raise ValueError(f"--k: values must be integers >= 1, got {v!r}")
        for name, value, low in (("trials", trials, 1), ("seed", seed, 0),
                                 ("max_steps", max_steps, 1), ("horizon", horizon, 1)):
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ValueError(f"--{name.replace('_', '-')}: must be an integer >= {low}, "
                                 f"got {value!r}")
        self.trials, self.seed, self.max_steps = int(trials), int(seed), int(max_steps)
        self.horizon = int(horizon)
        self.avoid_contradicted, self.relearn = bool(avoid_contradicted), bool(relearn)
        try:
            self.support_cell = Trial(object="rect1", support_cell=support_cell).support_cell
        except ValueError as exc:
            raise ValueError(f"--support-cell: {exc}") from None
        self._check_objects()

    def _check_objects(self) -> None:
        from push_core.objects import load_object

        for obj in self.objects:
            try:
                load_object(obj)
            except (ValueError, OSError, KeyError) as exc:
                raise ValueError(f"--objects: {obj!r}: {exc}") from None

    def as_dict(self) -> dict[str, Any]:
        return {"objects": self.objects, "tasks": self.tasks, "methods": self.methods,
                "k": [int(v) for v in self.k], "state": self.state, "com": self.com,
                "region": self.region, "com_estimation": self.com_estimation,
                "trials": self.trials, "seed": self.seed, "max_steps": self.max_steps,
                "horizon": self.horizon, "avoid_contradicted": self.avoid_contradicted,
                "relearn": self.relearn, "support_cell": self.support_cell}


def build_trials(opts: EvalOptions) -> list[Trial]:
    """All trials of the options' cells, cell by cell (module docstring)."""
    trials: list[Trial] = []
    seen: set[tuple[Any, ...]] = set()
    for obj, task, method, k, state, com, region, est in itertools.product(
            opts.objects, opts.tasks, opts.methods, opts.k, opts.state, opts.com, opts.region,
            opts.com_estimation):
        if method == "pushnet":
            k = opts.k[0]
        estimate = est == "on" or state == "gt"
        key = (obj, task, method, k, state, com, region, estimate)
        if key in seen:
            continue
        seen.add(key)
        trials += [Trial(object=obj, task=task, method=method, k=int(k), state=state, com=com,
                         region=region, index=i, seed=opts.seed, max_steps=opts.max_steps,
                         estimate_com=estimate, horizon=opts.horizon,
                         avoid_contradicted=opts.avoid_contradicted, relearn=opts.relearn,
                         support_cell=opts.support_cell)
                   for i in range(opts.trials)]
    return trials


# --------------------------------------------------------------------------------------------
# Running
# --------------------------------------------------------------------------------------------
def _init_worker() -> None:
    """Worker start-up: one thread per worker for torch, OpenCV and BLAS."""
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = "1"
    import cv2
    import torch

    torch.set_num_threads(1)
    cv2.setNumThreads(1)


def _safe_run(trial: Trial) -> dict[str, Any]:
    """:func:`pushbot.experiments.inprocess.run_trial`, an exception turned into a failed record."""
    from pushbot.experiments.inprocess import run_trial

    t0 = time.perf_counter()
    try:
        return run_trial(trial)
    except Exception as exc:  # noqa: BLE001 - one broken trial must not end the evaluation
        from push_core.episode import new_record

        return new_record(trial.as_dict(), perception_failures=0,
                          wall_s=time.perf_counter() - t0,
                          reason=f"error: {type(exc).__name__}: {exc}")


def _run_local(trials: list[Trial], workers: int,
               tick: Callable[[], None]) -> list[dict[str, Any]]:
    if workers <= 1:
        _init_worker()
        out = []
        for t in trials:
            out.append(_safe_run(t))
            tick()
        return out
    import multiprocessing as mp

    ctx = mp.get_context("forkserver")
    out = []
    with ctx.Pool(workers, initializer=_init_worker) as pool:
        for rec in pool.imap_unordered(_safe_run, trials, chunksize=1):
            out.append(rec)
            tick()
    return out


def _run_ray(trials: list[Trial], address: str,
             tick: Callable[[], None]) -> list[dict[str, Any]]:
    try:
        import ray
    except ImportError:
        raise ValueError("--ray needs the optional dependency ray: pip install 'pushbot[ray]' "
                         "(or pip install ray)") from None
    if not ray.is_initialized():
        ray.init(address=None if address == "local" else address, include_dashboard=False,
                 log_to_driver=False)

    @ray.remote(num_cpus=1)
    def remote(trial: Trial) -> dict[str, Any]:
        _init_worker()
        return _safe_run(trial)

    pending = [remote.remote(t) for t in trials]
    out = []
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        out.extend(ray.get(done))
        tick()
    return out


def _run_graph(trials: list[Trial], out_dir: Path, progress: bool, robot: str = "pusher"
               ) -> list[dict[str, Any]]:
    try:
        from pushbot.runner.episode import run_graph_trials
    except ImportError as exc:
        raise ValueError(f"--graph needs pushbot.runner.episode (the ROS-graph episodes), which "
                         f"is not available in this install: {exc}") from None
    return list(run_graph_trials(trials, out_dir=out_dir, progress=progress, robot=robot))


def _order(records: list[dict[str, Any]], trials: list[Trial]) -> list[dict[str, Any]]:
    """Records in the order of ``trials`` (workers finish in any order)."""
    position = {json.dumps(t.as_dict(), sort_keys=True): i for i, t in enumerate(trials)}
    return sorted(records, key=lambda r: position[json.dumps(r["trial"], sort_keys=True)])


def evaluate(opts: EvalOptions, *, workers: int | None = None, ray_address: str | None = None,
             graph: bool = False, out_dir: Path | str | None = None,
             progress: bool = True, robot: str = "pusher") -> dict[str, Any]:
    """Run the options' trials and summarise them (the ``results.json`` document).

    Parameters
    ----------
    opts : EvalOptions
    workers : int, optional
        Local worker processes (default: the usable cores); 1 runs in this process.
    ray_address : str, optional
        Run on Ray instead (``"local"`` starts a local cluster).
    graph : bool
        Run through the ROS graph (:mod:`pushbot.runner.episode`).
    robot : str
        With ``graph``: ``pusher`` (the simulator's finger) or ``arm`` (push_executor_node
        driving the simulated Panda).
    out_dir : path, optional
        Handed to the graph runner (its logs); the caller writes the outputs.
    progress : bool
        Progress bar on stderr.
    """
    trials = build_trials(opts)
    workers = usable_cores() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"--workers: must be >= 1, got {workers}")
    bar = None
    if progress and not graph:
        from tqdm import tqdm

        bar = tqdm(total=len(trials), unit="trial", desc="eval push", file=sys.stderr)
    tick = bar.update if bar is not None else (lambda: None)
    load_before = _load()
    t0 = time.perf_counter()
    try:
        if graph:
            records = _run_graph(trials, Path(out_dir or "out/eval"), progress, robot)
            engine = "graph" if robot == "pusher" else f"graph ({robot})"
        elif ray_address:
            records = _run_ray(trials, ray_address, tick)
            engine = f"ray ({ray_address})"
        else:
            records = _run_local(trials, workers, tick)
            engine = f"{workers} local worker process{'es' if workers > 1 else ''}"
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    records = _order(records, trials)
    return {"config": opts.as_dict(), "cells": summarise(records), "trials": records,
            "timing": {"wall_s": wall, "engine": engine, "workers": workers,
                       "load_before": load_before, "load_after": _load(),
                       "usable_cores": usable_cores()}}


def usable_cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else \
        (os.cpu_count() or 1)


def _load() -> list[float] | None:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return None


# --------------------------------------------------------------------------------------------
# Command line
# --------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot eval push``."""
    parser.add_argument("--objects", nargs="+", default=list(DEFAULT_OBJECTS),
                        help="library names or object specification files (default: the "
                             "held-out tri1 butter hex)")
    parser.add_argument("--tasks", nargs="+", default=list(TASKS),
                        help=f"tasks: {' '.join(TASKS)} (default: all)")
    parser.add_argument("--methods", nargs="+", default=["ana"],
                        help=f"methods: {' '.join(METHODS)} (default: ana)")
    parser.add_argument("--k", nargs="+", type=int, default=[3],
                        help="contact points sampled per step (default: 3)")
    parser.add_argument("--state", nargs="+", default=["gt"],
                        help="state sources: gt (ground truth) and/or filter (rendered RGB-D "
                             "-> segmentation -> EKF) (default: gt)")
    parser.add_argument("--com", nargs="+", default=["centre"],
                        help="COM: centre (geometric centre), random (uniform over the "
                             "outline shrunk by 30 %%), spec (the object specification's "
                             "com_offset) (default: centre)")
    parser.add_argument("--region", nargs="+", default=["small"],
                        help="goal regions: small (0.75 cm, 5 deg) medium (2.5 cm, 7.5 deg) "
                             "large (5 cm, 10 deg) (default: small)")
    parser.add_argument("--com-estimation", nargs="+", default=["on"],
                        help="filter: on (full EKF) and/or off (COM pinned at the centre) "
                             "(default: on)")
    parser.add_argument("--trials", type=int, default=60,
                        help="trials per cell (default 60 = 20 orientations x 3 runs)")
    parser.add_argument("--seed", type=int, default=0, help="base seed (default 0)")
    parser.add_argument("--max-steps", type=int, default=30, help="pushes allowed (default 30)")
    parser.add_argument("--horizon", type=int, default=1,
                        help="pushes the planner looks ahead (push_core.lookahead; default 1 = "
                             "greedy, the source's planner)")
    parser.add_argument("--avoid-contradicted", action="store_true",
                        help="the planner avoids the contact region of a push whose outcome "
                             "contradicted its prediction")
    parser.add_argument("--relearn", action="store_true",
                        help="filter: the EKF re-learns COM, limit surface and friction when "
                             "the pushes contradict the model")
    parser.add_argument("--support-cell", type=float, default=0.0, metavar="M",
                        help="the simulated object's support: 0 = its convex pieces whole "
                             "(each rests on 3-4 corners), 0.005-0.05 = cut into cells of this "
                             "size, m, supported across the footprint (default 0)")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes (default: the cores this process may use); 1 "
                             "runs in this process")
    parser.add_argument("--ray", metavar="ADDRESS", default=None,
                        help="run the trials as Ray tasks on this cluster ('local' starts one; "
                             "needs pip install 'pushbot[ray]')")
    parser.add_argument("--graph", action="store_true",
                        help="run the trials through the real ROS graph (pushbot.runner.episode)")
    parser.add_argument("--robot", default="pusher", choices=("pusher", "arm"),
                        help="with --graph: what executes the pushes, the simulator's free "
                             "pusher or push_executor_node driving the simulated Panda arm "
                             "(default %(default)s)")
    parser.add_argument("--out", default="out/eval",
                        help="output directory for results.json, figures and tables "
                             "(default out/eval)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def options_from_args(args: argparse.Namespace) -> EvalOptions:
    return EvalOptions(objects=args.objects, tasks=args.tasks, methods=args.methods, k=args.k,
                       state=args.state, com=args.com, region=args.region,
                       com_estimation=args.com_estimation, trials=args.trials, seed=args.seed,
                       max_steps=args.max_steps, horizon=args.horizon,
                       avoid_contradicted=args.avoid_contradicted, relearn=args.relearn,
                       support_cell=args.support_cell)


def run(args: argparse.Namespace) -> int:
    """Run ``pushbot eval push``: 0 on completion, 2 on bad options (message on stderr)."""
    try:
        opts = options_from_args(args)
        if args.ray and args.graph:
            raise ValueError("--ray and --graph exclude each other")
        if args.robot != "pusher" and not args.graph:
            raise ValueError(f"--robot {args.robot} needs --graph (the arm runs only in the "
                             "ROS graph)")
        if args.workers is not None and args.workers < 1:
            raise ValueError(f"--workers: must be >= 1, got {args.workers}")
        if args.ray:
            import importlib.util

            if importlib.util.find_spec("ray") is None:
                raise ValueError("--ray needs the optional dependency ray: pip install "
                                 "'pushbot[ray]' (or pip install ray)")
        out_dir = Path(args.out)
        doc = evaluate(opts, workers=args.workers, ray_address=args.ray, graph=args.graph,
                       out_dir=out_dir, progress=not args.no_progress, robot=args.robot)
    except ValueError as exc:
        print(f"pushbot eval push: error: {exc}", file=sys.stderr)
        return 2
    doc["timing"]["command"] = "pushbot " + " ".join(sys.argv[1:]) if sys.argv[1:] else None
    written = write_outputs(doc, out_dir)
    print(cells_markdown(doc["cells"]))
    print(f"\n{len(doc['trials'])} trials in {doc['timing']['wall_s']:.1f} s "
          f"({doc['timing']['engine']}); wrote {', '.join(str(p) for p in written)}")
    return 0
