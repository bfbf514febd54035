"""``pushbot eval pusht``: the push_core planner on Push-T (``gym_pusht/PushT-v0``).

Runs episodes of the learned-pushing benchmark with the env's own dynamics, reward and success
(`--obs state`: the env state; `--obs pixels`: its 96 x 96 image and the agent position, the
observation of Diffusion Policy) and writes ``OUT/results.json`` (top-level ``success_rate``,
``success_wilson_95``, ``avg_max_reward``, ``mean_max_coverage``, ``steps_mean``, ...,
``episodes``) and videos of the first K episodes (``OUT/videos``). The adapter, frames and
units: :mod:`pushbot.experiments.pusht.adapter`; pose from pixels:
:mod:`pushbot.experiments.pusht.vision`; ``--object-model estimated`` (the T unknown: outline
from the image, COM, limit surface and friction estimated online):
:mod:`pushbot.experiments.pusht.estimated`. Needs ``pip install 'pushbot[pusht]'``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot eval pusht``."""
    parser.add_argument("--episodes", type=int, default=50, help="episodes (default 50)")
    parser.add_argument("--seed0", type=int, default=0, help="seed of the first episode "
                        "(episode i uses seed seed0 + i; default 0)")
    parser.add_argument("--max-steps", type=int, default=300,
                        help="control steps per episode (default 300, the benchmark's)")
    parser.add_argument("--obs", choices=("state", "pixels"), default="state",
                        help="observation: the env state, or its 96 x 96 image + agent position")
    parser.add_argument("--out", type=Path, default=Path("out/pusht"),
                        help="output folder for results.json and videos (default out/pusht)")
    parser.add_argument("--video", type=int, default=0, metavar="K",
                        help="write videos of the first K episodes (default 0)")
    parser.add_argument("--workers", type=int, default=1,
                        help="worker processes (default 1)")
    parser.add_argument("--object-model", choices=("env", "estimated"), default="env",
                        help="the T's model: 'env' reads outline, COM, mass and moment from the "
                             "env's body (default); 'estimated' perceives the outline in the "
                             "image and estimates COM, limit surface and friction online (the "
                             "env's bodies and shapes sealed)")


def run(args: argparse.Namespace) -> int:
    """Run ``pushbot eval pusht``; prints the metrics, writes results.json."""
    from pushbot.experiments.pusht import adapter

    try:
        result = adapter.evaluate(args.episodes, args.seed0, args.max_steps, args.obs,
                                        args.out, args.video, args.workers, progress=True,
                                        object_model=args.object_model)
    except ImportError as exc:
        print(f"pushbot eval pusht: {exc}", file=sys.stderr)
        return 1
    lo, hi = result["success_wilson_95"]
    model = "" if args.object_model == "env" else ", estimated object model"
    print(f"Push-T ({args.obs}{model}): success {result['success_rate']:.3f} (95 % Wilson "
          f"[{lo:.3f}, {hi:.3f}]) over {result['n_episodes']} episodes, avg max reward "
          f"{result['avg_max_reward']:.3f}, mean max coverage {result['mean_max_coverage']:.3f},"
          f" steps {result['steps_mean']:.1f}; {args.out / 'results.json'}")
    return 0
