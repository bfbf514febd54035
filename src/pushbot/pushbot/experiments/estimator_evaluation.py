"""``pushbot eval estimator``: COM, l and m estimation and consistency of the EKF on pybullet.

For each object (butter, tri1, hex by default) and episode: the in-process pybullet world of
``sim_bridge.world`` with a randomised object (``WorldConfig(randomize=True, seed=...)``: mass
x[0.5, 2], COM uniform over the outline shrunk by 30 %, table friction 0.15-0.4, pusher friction
0.15-0.5) at a random orientation; one observation, then ``--pushes`` pushes, each followed
by an observation. Every push is drawn at a random outline point, toward the object's centre
+-30 deg, 2-4 cm after a 0.5-1.5 cm approach, planned at the *estimated* pose (redrawn until
the world accepts it; pushes bring the object back when it is more than 8 cm from the
workspace centre). ``--push-policy`` (one or both, comma-separated; each gets its own tables):
``active`` (default) executes, of 16 such draws, the one the filter expects to shrink its COM
covariance most (``push_core.estimator.active.most_informative_push``: the smallest trace of the
COM block of :meth:`push_core.estimator.PushEKF.expected_covariance`); ``random`` executes the
first draw. The filter (:class:`push_core.estimator.PushEKF`, default settings) gets what the
robot would get: the object's outline (library shape sampled every 2 mm with outward normals,
object frame), the executed pusher motion and the observed pose.

Observations (``--observations``, one or both, comma-separated; each gets its own tables):
``gt-noise`` = ground-truth pose plus Gaussian noise, 2 mm per position axis and 1.5 deg by
default (``--position-noise``, ``--angle-noise-deg``; the filter's R matches), with the library
outline. ``perception`` = the perception pipeline (``push_perception``) in this process, as
``pushbot eval perception`` runs it: after the first observation and every push the world
renders a 640 x 480 RGB-D frame (pusher parked out of view), the segmentation CNN
(``push_perception.model.Segmenter``, bundled weights, one torch thread) finds the object and
``push_perception.tracker.EpisodeTracker`` measures its pose (footprint centroid, orientation
relative to the episode's first frame) with its covariance, which the filter uses as R; the
filter's outline is the perception's (first frame). The truth is compared in the perception's
frame (orientation minus the true yaw of the first frame, library COM turned by that yaw).

Reported per object: COM error after 0, 1, 2, 3, 5 and all pushes (median, mean +- std) against
the "without estimation" baseline |c_true| (COM assumed at the centroid) and the target (median
<= 10 mm after 10 pushes on butter and tri1; the source: 17.7 +- 8.5 mm); l (no ground truth in
a physics engine: final / initial and its change over the last 3 pushes) and m (error to the
simulated pusher friction); NEES over (x, y, theta, c_x, c_y, m) and NIS with their chi-square
bands; gated observations. ``--write`` puts the report into
``docs/results/eval_estimator.md`` of the source checkout. The work is in
:mod:`pushbot.experiments.estimator_episodes`.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

__all__ = ["SECTION_ID", "add_arguments", "main", "run"]

DEFAULT_OBJECTS = ("butter", "tri1", "hex")
SECTION_ID = "eval_estimator"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of ``pushbot eval estimator``."""
    parser.add_argument("--objects", default=",".join(DEFAULT_OBJECTS),
                        help="comma-separated object names or spec files (default: "
                             "%(default)s)")
    parser.add_argument("--episodes", type=int, default=30, help="episodes per object "
                        "(default: %(default)s)")
    parser.add_argument("--pushes", type=int, default=10, help="pushes per episode (default: "
                        "%(default)s)")
    parser.add_argument("--seed", type=int, default=0, help="first seed; episode i uses "
                        "seed + i (default: %(default)s)")
    parser.add_argument("--observations", default="gt-noise",
                        help="pose observations, comma-separated: gt-noise (ground truth + "
                        "noise), perception (segmentation + pose on rendered frames) or both "
                        "(default: %(default)s)")
    parser.add_argument("--push-policy", default="active",
                        help="how pushes are chosen, comma-separated: active (the most "
                        "informative of 16 random draws), random (the first draw) or both "
                        "(default: %(default)s)")
    parser.add_argument("--position-noise", type=float, default=0.002,
                        help="observation noise per position axis, m (default: %(default)s)")
    parser.add_argument("--angle-noise-deg", type=float, default=1.5,
                        help="observation noise of the orientation, deg (default: "
                             "%(default)s)")
    parser.add_argument("--iterations", type=int, default=None,
                        help="linearisations per push (EKFConfig.iterations; default: the "
                             "filter's default, 2; 1 = plain EKF)")
    parser.add_argument("--write", action="store_true",
                        help=f"write the report into docs/results/{SECTION_ID}.md")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _results_module() -> ModuleType | None:
    """``benchmarks/_results.py`` of the source checkout this module lives in, if any."""
    for parent in Path(__file__).resolve().parents:
        candidate = parent / "benchmarks" / "_results.py"
        if candidate.is_file():
            spec = importlib.util.spec_from_file_location("_pushbot_results", candidate)
            assert spec is not None and spec.loader is not None
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            return module
    return None


def _comma_list(option: str, value: str, allowed: Sequence[str]) -> list[str] | None:
    """The non-empty comma-separated entries of ``value``, all in ``allowed``; None (and a
    message on stderr) otherwise."""
    items = [o.strip() for o in value.split(",") if o.strip()]
    if not items or any(o not in allowed for o in items):
        print(f"pushbot eval estimator: {option} must be a comma-separated list of "
              f"{', '.join(allowed)}, got {value!r}", file=sys.stderr)
        return None
    return items


def run(args: argparse.Namespace, argv: Sequence[str] | None = None) -> int:
    """Run the evaluation for parsed ``args``; returns the exit code (2 on bad arguments)."""
    from pushbot.experiments.estimator_episodes import OBSERVATIONS, PUSH_POLICIES

    sources = _comma_list("--observations", args.observations, OBSERVATIONS)
    policies = _comma_list("--push-policy", args.push_policy, PUSH_POLICIES)
    if sources is None or policies is None:
        return 2
    names = [n.strip() for n in args.objects.split(",") if n.strip()]
    if args.episodes < 1 or args.pushes < 1 or not names:
        print("pushbot eval estimator: --episodes and --pushes must be >= 1 and --objects "
              "non-empty", file=sys.stderr)
        return 2
    if args.iterations is not None and not 1 <= args.iterations <= 10:
        print("pushbot eval estimator: --iterations must be in [1, 10]", file=sys.stderr)
        return 2
    if not (args.position_noise > 0 and args.angle_noise_deg > 0):
        print("pushbot eval estimator: --position-noise and --angle-noise-deg must be > 0",
              file=sys.stderr)
        return 2
    from tqdm import tqdm

    from push_core.estimator import EKFConfig
    from push_core.objects import load_object
    from pushbot.experiments.estimator_episodes import load_perception, report, run_physics_episode

    for name in names:
        try:
            load_object(name)
        except ValueError as exc:
            print(f"pushbot eval estimator: {exc}", file=sys.stderr)
            return 2
    angle_noise = math.radians(args.angle_noise_deg)
    config = EKFConfig() if args.iterations is None else EKFConfig(iterations=args.iterations)
    bodies = []
    runs = [(source, policy) for source in sources for policy in policies]
    for source, policy in runs:
        segmenter = load_perception() if source == "perception" else None
        episodes: dict[str, list] = {n: [] for n in names}
        t0 = time.perf_counter()
        jobs = [(n, args.seed + i) for n in names for i in range(args.episodes)]
        with tqdm(jobs, desc=f"episodes ({source}, {policy})", unit="ep",
                  disable=args.no_progress, file=sys.stderr) as bar:
            for name, seed in bar:
                bar.set_postfix_str(f"{name} seed {seed}")
                episodes[name].append(run_physics_episode(
                    name, seed, args.pushes, config, args.position_noise, angle_noise,
                    observations=source, segmenter=segmenter, policy=policy))
        body = report(episodes, args.pushes, args.position_noise, angle_noise,
                      time.perf_counter() - t0, observations=source,
                      notes=(source, policy) == runs[-1])
        title = f"### Observations: {source}, pushes: {policy}"
        bodies.append(body if len(runs) == 1 else f"{title}\n\n{body}")
    body = "\n\n".join(bodies)
    shown = list(argv) if argv is not None else sys.argv[1:]
    if shown[:2] == ["eval", "estimator"]:  # called as `pushbot eval estimator ...`
        shown = shown[2:]
    command = " ".join(["pushbot eval estimator", *shown]).strip()
    results = _results_module() if args.write else None
    if args.write and results is None:
        print("--write needs the source checkout (benchmarks/_results.py not found); printing "
              "only", file=sys.stderr)
    if results is not None:
        section = results.format_section(
            "COM, l and m estimation on pybullet physics (`eval_estimator`)", command, body)
        results.update_section(SECTION_ID, section)
        print(section)
    else:
        print(body)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m pushbot.experiments.estimator_evaluation [options]``; the same as ``pushbot eval
    estimator``."""
    parser = argparse.ArgumentParser(prog="pushbot eval estimator",
                                     description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    return run(args, argv)


if __name__ == "__main__":
    raise SystemExit(main())
