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
  docs/ARCHITECTURE.md, in trial order) and ``timing`` (total wall time, workers, load).
  Wall times are only in ``timing`` keys and the records' ``wall_s`` / ``planning_ms``; the rest
  is a deterministic function of the options (:func:`deterministic_view`), so the same seed
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
import dataclasses
import itertools
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.runner.protocol import COM_MODES, METHODS, REGIONS, STATE_SOURCES, TASKS, Trial

__all__ = [
    "EvalOptions",
    "add_arguments",
    "build_trials",
    "cell_key",
    "deterministic_view",
    "evaluate",
    "run",
    "summarise",
    "table_5_1",
    "table_5_2",
]

DEFAULT_OBJECTS = ("tri1", "butter", "hex")
#: Keys that hold wall-clock measurements (not part of the deterministic result).
TIMING_KEYS = frozenset({"timing", "wall_s", "planning_ms"})
#: Trial fields that define a cell (everything except the index).
CELL_FIELDS = ("object", "task", "method", "k", "state", "com", "region", "estimate_com",
               "seed", "max_steps", "horizon", "avoid_contradicted", "relearn", "support_cell")

#: The source's Table 5.1 (mixed task, ana, COM at the centre): steps, end error mm, deg.
SOURCE_TABLE_5_1 = {"gt": ((7.3, 3.6), (5.0, 1.8), (1.8, 1.3)),
                    "filter": ((7.1, 3.1), (8.7, 4.2), (3.0, 2.2))}
#: The source's Table 5.2 (mixed task, random COM): (success, steps) per object.
SOURCE_TABLE_5_2 = {
    ("lrn", False): {"butter": (0.75, 13.9), "tri1": (0.75, 12.96), "hex": (0.92, 13.2)},
    ("lrn", True): {"butter": (0.91, 10.6), "tri1": (0.93, 11.86), "hex": (0.88, 11.4)},
    ("ana", False): {"butter": (0.82, 12.1), "tri1": (0.90, 13.3), "hex": (0.85, 10.5)},
    ("ana", True): {"butter": (0.90, 11.4), "tri1": (0.98, 10.9), "hex": (0.90, 10.7)},
}


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


#: Defaults of the trial fields that have one: a record written before a field existed
#: (e.g. ``horizon``) belongs to the cell of the default.
_TRIAL_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Trial)
                   if f.default is not dataclasses.MISSING}


def cell_key(trial: dict[str, Any]) -> tuple[Any, ...]:
    """The cell of a trial (``Trial.as_dict()``): every field except the index."""
    return tuple(trial[f] if f in trial else _TRIAL_DEFAULTS[f] for f in CELL_FIELDS)


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
# Statistics
# --------------------------------------------------------------------------------------------
def _mean_std(values: list[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    a = np.asarray(values, dtype=float)
    return float(a.mean()), float(a.std())


def stats(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Success rate, steps (successful trials), true end errors and COM error (all trials),
    reasons; ``timing`` with the planning-time median and the mean episode wall time."""
    n = len(records)
    ok = [r for r in records if r["success"]]
    out: dict[str, Any] = {"n": n, "successes": len(ok),
                           "success_rate": len(ok) / n if n else None}
    out["steps_mean"], out["steps_std"] = _mean_std([r["steps"] for r in ok])
    for key in ("end_error_xy", "end_error_theta", "com_error"):
        vals = [r[key] for r in records if r.get(key) is not None]
        out[f"{key}_mean"], out[f"{key}_std"] = _mean_std(vals)
    reasons: dict[str, int] = {}
    for r in records:
        reason = r["reason"] if not r["reason"].startswith("error") else "error"
        reasons[reason] = reasons.get(reason, 0) + 1
    out["reasons"] = dict(sorted(reasons.items()))
    planning = [ms for r in records for ms in r.get("planning_ms", [])]
    out["timing"] = {"planning_ms_median": float(np.median(planning)) if planning else None,
                     "wall_s_mean": float(np.mean([r["wall_s"] for r in records]))
                     if records else None}
    return out


def summarise(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One record per cell (in first-appearance order): the cell's fields and :func:`stats`."""
    cells: dict[tuple[Any, ...], list[dict[str, Any]]] = {}
    for r in records:
        cells.setdefault(cell_key(r["trial"]), []).append(r)
    return [{**dict(zip(CELL_FIELDS, key, strict=True)), **stats(recs)}
            for key, recs in cells.items()]


def deterministic_view(doc: Any) -> Any:
    """``doc`` without the wall-clock keys (:data:`TIMING_KEYS`), for comparing runs."""
    if isinstance(doc, dict):
        return {k: deterministic_view(v) for k, v in doc.items() if k not in TIMING_KEYS}
    if isinstance(doc, list):
        return [deterministic_view(v) for v in doc]
    return doc


def _select(records: list[dict[str, Any]], **fields: Any) -> list[dict[str, Any]]:
    return [r for r in records if all(r["trial"][k] == v for k, v in fields.items())]


# --------------------------------------------------------------------------------------------
# Tables and figures
# --------------------------------------------------------------------------------------------
def _pm(mean: float | None, std: float | None, scale: float = 1.0, fmt: str = ".1f") -> str:
    if mean is None:
        return "-"
    return f"{mean * scale:{fmt}} +- {std * scale:{fmt}}"


def table_5_1(records: list[dict[str, Any]]) -> str | None:
    """Table 5.1: mixed task, ana, COM at the centre, small region; gt vs filter, all objects
    together. None when the records hold neither row."""
    rows = []
    for state, label in (("gt", "ground-truth state"), ("filter", "EKF state (full system)")):
        recs = _select(records, task="mixed", method="ana", com="centre", state=state,
                       region="small", estimate_com=True)
        if not recs:
            continue
        s = stats(recs)
        src = SOURCE_TABLE_5_1[state]
        objs = sorted({r["trial"]["object"] for r in recs})
        rows.append(
            f"| {label} | {', '.join(objs)} | {s['n']} | {s['success_rate']:.3f} | "
            f"{_pm(s['steps_mean'], s['steps_std'])} | "
            f"{_pm(s['end_error_xy_mean'], s['end_error_xy_std'], 1e3)} | "
            f"{_pm(s['end_error_theta_mean'], s['end_error_theta_std'], 180 / math.pi)} | "
            f"{src[0][0]} +- {src[0][1]} | {src[1][0]} +- {src[1][1]} | "
            f"{src[2][0]} +- {src[2][1]} |")
    if not rows:
        return None
    return "\n".join([
        "Table 5.1 (mixed task, ana, COM at the geometric centre, small goal region). Steps "
        "over the successful trials; true end errors (mm, deg; orientation modulo the object's "
        "symmetry) over all trials; mean +- std.",
        "",
        "| state | objects | trials | success | steps | end error mm | end error deg | "
        "source steps | source mm | source deg |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *rows])


def table_5_2(records: list[dict[str, Any]]) -> str | None:
    """Table 5.2: mixed task, random COM, filter, small region: success / steps per object for
    ana and lrn without and with COM estimation. None when the records hold no row."""
    objects = sorted({r["trial"]["object"] for r in records})
    rows = []
    for method, est in (("lrn", False), ("lrn", True), ("ana", False), ("ana", True)):
        cells = []
        any_data = False
        for obj in objects:
            recs = _select(records, task="mixed", method=method, com="random", state="filter",
                           region="small", estimate_com=est, object=obj)
            src = SOURCE_TABLE_5_2[(method, est)].get(obj)
            src_txt = f" (source {src[0]:.2f} / {src[1]:g})" if src else ""
            if recs:
                any_data = True
                s = stats(recs)
                steps = f"{s['steps_mean']:.1f}" if s["steps_mean"] is not None else "-"
                cells.append(f"{s['success_rate']:.2f} / {steps}{src_txt}")
            else:
                cells.append("-")
        if any_data:
            rows.append(f"| {method}{' + COM' if est else ''} | " + " | ".join(cells) + " |")
    if not rows:
        return None
    n = {len(_select(records, task="mixed", com="random", state="filter", region="small",
                     object=o, method=m, estimate_com=e))
         for o in objects for m in ("ana", "lrn") for e in (False, True)} - {0}
    return "\n".join([
        "Table 5.2 (mixed task, random COM, EKF state, small goal region): success rate / mean "
        'steps of the successful trials per object; "+ COM" = full EKF, without = the EKF '
        "with the COM pinned at the geometric centre. The source's figures in brackets "
        f"(trials per method and object: {', '.join(map(str, sorted(n)))}).",
        "",
        "| method | " + " | ".join(objects) + " |",
        "| --- | " + " | ".join("---" for _ in objects) + " |",
        *rows])


def _plot_versus(records: list[dict[str, Any]], x_field: str, x_values: list[Any],
                 methods: Sequence[str], path: Path, title: str, x_label: str) -> bool:
    """Success rate and mean steps vs ``x_field`` per task (columns) and method (lines)."""
    methods = [m for m in methods if _select(records, method=m)]
    if not methods:
        return False
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tasks = [t for t in TASKS if _select(records, task=t)]
    fig, axes = plt.subplots(2, len(tasks), figsize=(max(4.2 * len(tasks), 7.0), 6.4),
                             squeeze=False)
    xs = list(range(len(x_values)))
    for j, task in enumerate(tasks):
        for method in methods:
            succ, steps = [], []
            for x in x_values:
                recs = _select(records, task=task, method=method, **{x_field: x})
                s = stats(recs) if recs else None
                succ.append(s["success_rate"] if s else np.nan)
                steps.append(s["steps_mean"] if s and s["steps_mean"] is not None else np.nan)
            axes[0, j].plot(xs, succ, marker="o", label=method)
            axes[1, j].plot(xs, steps, marker="o", label=method)
        axes[0, j].set_title(task)
        axes[0, j].set_ylim(-0.02, 1.02)
        axes[0, j].set_ylabel("success rate")
        axes[1, j].set_ylabel("mean steps (successful)")
        for i in range(2):
            axes[i, j].set_xticks(xs, [str(x) for x in x_values])
            axes[i, j].set_xlabel(x_label)
            axes[i, j].grid(alpha=0.3)
    axes[0, 0].legend()
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def write_outputs(doc: dict[str, Any], out_dir: Path) -> list[Path]:
    """``results.json``, the figures and ``tables.md`` in ``out_dir``; returns the paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "results.json"]
    written[0].write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    records = doc["trials"]
    ks = sorted({r["trial"]["k"] for r in records if r["trial"]["method"] != "pushnet"})
    regions = [r for r in REGIONS if _select(records, region=r)]
    if ks:
        small = [r for r in records if r["trial"]["region"] == "small"]
        for name, methods, title in (
                ("fig5_5.png", ("ana", "lrn", "geo", "rdn"),
                 "Fig. 5.5: contact selection vs number of sampled contact points k"),
                ("fig5_6.png", ("ana", "ana-direct", "lrn", "lrn-direct"),
                 "Fig. 5.6: push optimisation (rollouts) vs direct affordances")):
            if _plot_versus(small, "k", ks, methods, out_dir / name, title, "k"):
                written.append(out_dir / name)
    if _select(records, method="pushnet") and regions:
        if _plot_versus(records, "region", regions, ("ana", "pushnet"), out_dir / "fig5_7.png",
                        "Fig. 5.7: goal region size, ana vs Push-Net-style baseline",
                        "goal region"):
            written.append(out_dir / "fig5_7.png")
    tables = [t for t in (table_5_1(records), table_5_2(records)) if t]
    if tables:
        (out_dir / "tables.md").write_text("\n\n".join(tables) + "\n", encoding="utf-8")
        written.append(out_dir / "tables.md")
    return written


def variant_label(cell: dict[str, Any]) -> str:
    """The planner and filter variant of a cell or trial dict (issue 22): ``greedy`` or the
    horizon and adaptations, e.g. ``H=2, avoid contradicted, relearn``, and the simulated
    object's support when cut into cells (``support 15 mm``)."""
    horizon = int(cell.get("horizon", 1))
    parts = ["greedy" if horizon == 1 else f"H={horizon}"]
    parts += [name.replace("_", " ") for name in ("avoid_contradicted", "relearn")
              if cell.get(name)]
    if cell.get("support_cell"):
        parts.append(f"support {1e3 * float(cell['support_cell']):g} mm")
    return ", ".join(parts)


def cells_markdown(cells: list[dict[str, Any]]) -> str:
    """The per-cell table (what ``pushbot eval push`` prints)."""
    lines = ["| object | task | method | k | state | com | region | COM est. | variant | n | "
             "success | steps | end mm | end deg | COM mm | plan ms |",
             "| --- " * 16 + "|"]
    for c in cells:
        plan = c["timing"]["planning_ms_median"]
        com = _pm(c["com_error_mean"], c["com_error_std"], 1e3)
        lines.append(
            f"| {c['object']} | {c['task']} | {c['method']} | {c['k']} | {c['state']} | "
            f"{c['com']} | {c['region']} | {'on' if c['estimate_com'] else 'off'} | "
            f"{variant_label(c)} | {c['n']} | "
            f"{c['success_rate']:.2f} | {_pm(c['steps_mean'], c['steps_std'])} | "
            f"{_pm(c['end_error_xy_mean'], c['end_error_xy_std'], 1e3)} | "
            f"{_pm(c['end_error_theta_mean'], c['end_error_theta_std'], 180 / math.pi)} | "
            f"{com if c['state'] == 'filter' else '-'} | "
            f"{'-' if plan is None else f'{plan:.1f}'} |")
    return "\n".join(lines)


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
