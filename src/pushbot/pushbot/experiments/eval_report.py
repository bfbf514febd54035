"""The report of ``pushbot eval push``: per-cell statistics, the source's Tables 5.1 and 5.2
next to ours, Figs. 5.5-5.7 and the per-cell Markdown table, from the episode records.

A *cell* is every trial field except the index (:data:`CELL_FIELDS`); records written before
a field existed belong to the cell of its default. Everything here is a deterministic function
of the records except the wall-clock keys (:data:`TIMING_KEYS`, left out by
:func:`deterministic_view`). :mod:`pushbot.experiments.evaluate` runs the trials and writes
this report.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pushbot.runner.protocol import REGIONS, TASKS, Trial

__all__ = [
    "CELL_FIELDS",
    "SOURCE_TABLE_5_1",
    "SOURCE_TABLE_5_2",
    "TIMING_KEYS",
    "cell_key",
    "cells_markdown",
    "deterministic_view",
    "stats",
    "summarise",
    "table_5_1",
    "table_5_2",
    "variant_label",
    "write_outputs",
]

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


#: Defaults of the trial fields that have one: a record written before a field existed
#: (e.g. ``horizon``) belongs to the cell of the default.
_TRIAL_DEFAULTS = {f.name: f.default for f in dataclasses.fields(Trial)
                   if f.default is not dataclasses.MISSING}


def cell_key(trial: dict[str, Any]) -> tuple[Any, ...]:
    """The cell of a trial (``Trial.as_dict()``): every field except the index."""
    return tuple(trial[f] if f in trial else _TRIAL_DEFAULTS[f] for f in CELL_FIELDS)


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
    """The planner and filter variant of a cell or trial dict: ``greedy`` or the
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
