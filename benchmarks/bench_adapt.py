"""Worlds that contradict the model: does the loop recover, and does it repeat
futile pushes?

The protocol's in-process episodes (``pushbot.experiments.inprocess.EpisodeRunner``, mixed task,
COM at the centre unless said) in pybullet worlds whose contact physics departs from what the loop
assumes, each changed by a :class:`ContradictingWorld` hook before every push:

- ``friction_jump``: the pusher-object friction jumps to 0.9 after the second push (the
  ``gt`` state and the filter's prior keep the trial's 0.15-0.5);
- ``sticky_patch``: the table friction is 0.8 while the object's centre is at x > 3 cm (a
  patch of high table friction that about half of the paths cross; the trial's is 0.15-0.4);
- ``com_edge``: the true COM at 80 % of the way from the centroid to the outline's farthest
  point along the object's x axis (the ``gt`` state gets the true COM; the filter starts at
  the centre).

Variants: ``greedy`` (the current loop) and ``lookahead+adapt`` (``horizon`` 2,
``avoid_contradicted`` and, with ``filter``, the estimator's ``relearn``), as in
``bench_lookahead``. ``futile repeats``: pushes made at the same contact region (object frame,
within ``push_core.planner.AVOID_RADIUS``) as the previous push after that push gained less
than a quarter of the true eq. (5.1) score to the goal (lambda 2 mm/deg) - "the same
useless push again", whether or not the model predicted it. ``contradicted repeats``: the
adaptation's acceptance test, pushes at the contact region of an earlier push of the episode whose
outcome contradicted its prediction (:func:`push_core.episode.contradiction`, rule 8, on the
state source's poses: what the loop could know).

Writes ``docs/results/bench_adapt.md`` (``bench_adapt_filter`` with
``--state filter``).

Usage::

    .venv/bin/python benchmarks/bench_adapt.py [--state gt|filter] [--trials N]
        [--objects ...] [--worlds ...] [--no-write]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _pushes import pushes_over_minimum  # noqa: E402
from _results import format_section, update_section  # noqa: E402
from bench_lookahead import variant_fields  # noqa: E402

from push_core.episode import contradiction  # noqa: E402
from push_core.geometry import world_to_object  # noqa: E402
from push_core.objects import load_object  # noqa: E402
from push_core.planner import AVOID_RADIUS, motion_score  # noqa: E402
from pushbot.experiments.inprocess import EpisodeRunner  # noqa: E402
from pushbot.runner.protocol import Trial, make_trials  # noqa: E402
from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout  # noqa: E402

WORLDS = ("friction_jump", "sticky_patch", "com_edge")
VARIANTS = ("greedy", "lookahead+adapt")
#: Pushes looked ahead by ``lookahead+adapt``.
HORIZON = 2
TARGET = 0.95


class ContradictingWorld(PushWorld):
    """A :class:`PushWorld` whose physics is changed before each push (module docstring)."""

    kind = "friction_jump"

    def reset(self, config: WorldConfig | None = None) -> None:
        super().reset(config)
        self.pushes = 0

    def execute_push(self, approach: Any, contact: Any, end: Any, *args: Any,
                     **kwargs: Any) -> Any:
        client, scene = self._client, self._scene  # the world's own pybullet bodies
        if self.kind == "friction_jump" and self.pushes == 2:
            client.changeDynamics(scene.pusher, -1, lateralFriction=0.9)
        elif self.kind == "sticky_patch":
            inside = self.object_pose()[0] > 0.03
            friction = 0.8 if inside else self.object_spec.friction_table
            client.changeDynamics(scene.table, -1, lateralFriction=friction)
        self.pushes += 1
        return super().execute_push(approach, contact, end, *args, **kwargs)


class WorldRunner(EpisodeRunner):
    """The protocol's episode runner in a :class:`ContradictingWorld` of one kind."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind = kind

    def _make_world(self, trial: Trial) -> Any:
        kwargs = trial.world_kwargs()
        if self.kind == "com_edge":
            outline = load_object(trial.object).polyline()
            kwargs["com_offset"] = (0.8 * float(np.max(outline[:, 0])), 0.0)
        cfg = WorldConfig(**kwargs)
        with quiet_stdout():
            if self._world is None:
                self._world = ContradictingWorld(cfg)
            else:
                self._world.reset(cfg)
        self._world.kind = self.kind
        return self._world


def futile_repeats(rec: dict) -> int:
    """Pushes at the previous push's contact region after it gained < 1/4 (module docstring)."""
    poses, pushes = np.asarray(rec["poses_true"]), rec["pushes"]
    est = np.asarray(rec["poses_est"])
    if len(pushes) < 2 or len(poses) < len(pushes) or len(est) < len(pushes):
        return 0
    trial = Trial(**rec["trial"])
    goal = poses[0] + trial.goal_offset()
    contact = [world_to_object(est[i], np.asarray(p[1])) for i, p in enumerate(pushes)]
    count = 0
    for i in range(1, len(pushes)):
        if i + 1 > len(poses) - 1:
            break
        before = float(motion_score(goal - poses[i - 1], 2.0))
        after = float(motion_score(goal - poses[i], 2.0))
        futile = before - after < 0.25 * before
        if futile and np.linalg.norm(contact[i] - contact[i - 1]) <= AVOID_RADIUS:
            count += 1
    return count


def contradicted_repeats(rec: dict) -> int:
    """Pushes at the contact region of an earlier push whose outcome contradicted its
    prediction (module docstring)."""
    pushes, est = rec["pushes"], np.asarray(rec["poses_est"])
    pred = np.asarray(rec.get("poses_predicted", []), dtype=float).reshape(-1, 3)
    n = min(len(pushes), len(pred), len(est) - 1)
    if n < 2:
        return 0
    # the goal the loop pursued: in the state source's frame (filter: yaw since the first
    # frame), as pushbot.experiments.inprocess sets it
    goal = est[0] + Trial(**rec["trial"]).goal_offset()
    contact = [world_to_object(est[i], np.asarray(pushes[i][1])) for i in range(n)]
    bad: list[np.ndarray] = []
    count = 0
    for i in range(n):
        if any(np.linalg.norm(contact[i] - b) <= AVOID_RADIUS for b in bad):
            count += 1
        if contradiction(est[i], pred[i], est[i + 1], goal, 2.0) is not None:
            bad.append(contact[i])
    return count


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--state", default="gt", choices=("gt", "filter"))
    parser.add_argument("--trials", type=int, default=10, help="trials per object and world")
    parser.add_argument("--objects", nargs="+", default=["butter", "tri1"])
    parser.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=WORLDS)
    parser.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    load_before = " ".join(f"{v:.2f}" for v in os.getloadavg())
    rows = ["| world | variant | success | pushes | pushes / min | futile repeats (episodes "
            "with any) | contradicted repeats (episodes with any) | target |",
            "| --- " * 8 + "|"]
    for kind in args.worlds:
        for variant in args.variants:
            runner = WorldRunner(kind)
            recs = []
            for trial in make_trials(args.objects, ["mixed"], ["ana"], [3], args.trials,
                                     state=args.state, **variant_fields(variant, HORIZON)):
                rec = runner.run(trial)
                recs.append(rec)
                print(f"{kind} {variant} {trial.object} #{trial.index}: {rec['steps']} "
                      f"pushes, {'ok' if rec['success'] else 'FAILED ' + rec['reason']}, "
                      f"futile repeats {futile_repeats(rec)}, contradicted repeats "
                      f"{contradicted_repeats(rec)}", flush=True)
            runner.close()
            ok = [r for r in recs if r["success"]]
            rate = len(ok) / len(recs)
            repeats = [futile_repeats(r) for r in recs]
            again = [contradicted_repeats(r) for r in recs]
            ratio = pushes_over_minimum(recs)
            rows.append(f"| {kind} | {variant} | {len(ok)}/{len(recs)} | "
                        f"{np.mean([r['steps'] for r in ok]) if ok else float('nan'):.2f} | "
                        f"{'-' if ratio is None else f'{ratio:.2f}'} | {sum(repeats)} "
                        f"({sum(r > 0 for r in repeats)}) | {sum(again)} "
                        f"({sum(r > 0 for r in again)}) | >= {TARGET}: "
                        f"{'met' if rate >= TARGET else 'NOT met'} |")
            print(rows[-1], flush=True)
    load_after = " ".join(f"{v:.2f}" for v in os.getloadavg())
    body = "\n".join([
        f"Mixed task, {', '.join(args.objects)} x {args.trials} trials per world and variant, "
        f"state `{args.state}`; worlds and the futile-repeat count in the module docstring "
        "of benchmarks/bench_adapt.py. 1/5/15-minute load average "
        f"{load_before} before, {load_after} after.",
        "",
        *rows,
        "",
        f"Wall time {(time.perf_counter() - t0) / 60:.1f} min.",
    ])
    command = " ".join(["python benchmarks/bench_adapt.py", *(argv or sys.argv[1:])])
    section_id = "bench_adapt" + ("" if args.state == "gt" else f"_{args.state}")
    section = format_section(f"Worlds that contradict the model, state {args.state} "
                             f"(`{section_id}`)", command, body)
    print(section)
    if not args.no_write:
        update_section(section_id, section)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
