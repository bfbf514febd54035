"""Training data for the learned affordance model: pybullet pushes (docs/design/planner.md).

ROS-free; uses the sim bridge's pybullet world (:class:`sim_bridge.world.PushWorld`, default
physics) in this process. ``pushbot data affordances --n N --out DIR`` is the command line.

One **sample** is one object instance at rest at a random orientation at the workspace
centre, with randomised physics (``WorldConfig(randomize=True)``: mass x[0.5, 2], COM uniform
over the outline shrunk by 30 %, table friction 0.15-0.4, pusher friction 0.15-0.5), and
``points_per_sample`` (20) contact points drawn uniformly from its outline (sampled every
2 mm, ``ObjectSpec.outline``), each pushed with the 10 representative pushes
(:func:`push_core.model.representative_pushes`: 0, +-30, +-60 degrees from the inward normal;
1 cm and 5 cm past the touching position; the pusher is lowered ``gap`` = 3 mm before it and
moves at 20 mm/s). Every push starts from the same resting pose (``set_object_pose``). The
label is what :func:`push_core.model.predict_motion` predicts: the displacement of the object
frame origin expressed in the object frame before the push, and the rotation.

Objects: with probability ``library_fraction`` a library object other than the held-out test
objects (``push_core.objects.TEST_OBJECTS`` = tri1, butter, hex), otherwise a procedural shape
from :func:`pushbot.experiments.perception_data.random_shape` (convex polygons, ellipses,
stars, smooth blobs with waists, L/T shapes; 5-18 cm). ``--test`` instead draws only the
held-out objects (the evaluation set).

Files: ``DIR/shard_00000.npz`` ... with ``shard_size`` samples each (the last
one may be shorter), shard ``k`` generated from
``numpy.random.SeedSequence([seed, k])`` only (reproducible, resumable: existing shards are
kept), and ``DIR/meta.json``. Arrays (S samples, P = points_per_sample, 10 pushes):
``motion`` (S, P, 10, 3) float32 (m, m, rad), ``valid`` (S, P, 10) bool (False where the world
refused the push, e.g. an approach point inside a concavity), ``touched`` (S, P, 10),
``points`` / ``normals`` (S, P, 2) the contact points and outward normals (object frame),
``com`` (S, 2), ``mass``, ``friction_table``, ``friction_pusher``, ``l_guess`` (S,),
``theta0`` (S,) the start orientation, ``object`` (S,) names, and the whole outline of each
sample as ``outline_points`` / ``outline_normals`` (M, 2) with ``outline_offsets`` (S + 1,).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.geometry import world_to_object, wrap_angle
from push_core.model import REPRESENTATIVE_ANGLES_DEG, REPRESENTATIVE_LENGTHS
from push_core.objects import TEST_OBJECTS, library_names

__all__ = ["DataConfig", "add_arguments", "generate", "generate_shard", "load", "run"]

FORMAT_VERSION = 1
#: Smallest training set ``pushbot train affordances`` accepts (one sample is held out).
MIN_TRAINING_SAMPLES = 2


@dataclass(frozen=True)
class DataConfig:
    """What a data set is made of (stored in ``meta.json``).

    Attributes
    ----------
    n_samples : int
        Object samples in total, >= 1 (the last shard may be shorter).
    seed : int
    shard_size : int
        Samples per file.
    points_per_sample : int
        Contact points per sample, each with the 10 representative pushes.
    library_fraction : float
        Probability of a library (training) object instead of a procedural shape.
    test : bool
        Draw only the held-out test objects (evaluation set).
    outline_spacing : float
        Spacing of the outline points, metres.
    gap : float
        Pusher lowered this far before the touching position along the push, metres.
    """

    n_samples: int = 500
    seed: int = 0
    shard_size: int = 10
    points_per_sample: int = 20
    library_fraction: float = 0.4
    test: bool = False
    outline_spacing: float = 0.002
    gap: float = 0.003

    def __post_init__(self) -> None:
        for name in ("n_samples", "shard_size", "points_per_sample"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < 1:
                raise ValueError(f"{name}: expected an integer >= 1, got {value!r}")
        if self.seed < 0:
            raise ValueError(f"seed: expected an integer >= 0, got {self.seed!r}")

    @property
    def n_shards(self) -> int:
        """Number of shards, ``ceil(n_samples / shard_size)``."""
        return -(-self.n_samples // self.shard_size)

    def shard_length(self, index: int) -> int:
        """Samples in shard ``index`` (the last one may be short)."""
        if not 0 <= index < self.n_shards:
            raise ValueError(f"shard index {index} outside [0, {self.n_shards})")
        return min(self.shard_size, self.n_samples - index * self.shard_size)


def _objects(test: bool) -> tuple[str, ...]:
    if test:
        return tuple(TEST_OBJECTS)
    return tuple(n for n in library_names() if n not in TEST_OBJECTS)


def generate_shard(cfg: DataConfig, index: int, workdir: Path) -> dict[str, NDArray[Any]]:
    """Simulate shard ``index`` (deterministic in ``(cfg, index)``); arrays as in the module
    docstring."""
    from pushbot.experiments.perception_data import random_shape
    from sim_bridge.world import PushWorld, WorldConfig, push_points

    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, index]))
    angles = np.radians(np.array(REPRESENTATIVE_ANGLES_DEG))
    pushes = [(a, length) for length in REPRESENTATIVE_LENGTHS for a in angles]  # length-major
    records: list[dict[str, Any]] = []
    world = None
    try:
        for s in range(cfg.shard_length(index)):
            names = _objects(cfg.test)
            if cfg.test or rng.random() < cfg.library_fraction:
                obj = names[int(rng.integers(len(names)))]
                name = obj
            else:
                spec_dict = random_shape(rng)
                name = f"proc_{index:05d}_{s:03d}"
                path = workdir / f"{name}.json"
                path.write_text(json.dumps({"name": name, **spec_dict}))
                obj = str(path)
            wcfg = WorldConfig(object=obj, randomize=True, seed=int(rng.integers(2**31 - 1)))
            if world is None:
                world = PushWorld(wcfg)
            else:
                world.reset(wcfg)
            spec = world.object_spec
            points, normals = spec.outline(cfg.outline_spacing)
            theta0 = float(rng.uniform(-math.pi, math.pi))
            start = np.array([0.0, 0.0, theta0])
            idx = rng.choice(len(points), size=min(cfg.points_per_sample, len(points)),
                             replace=False)
            motion = np.full((len(idx), len(pushes), 3), np.nan, dtype=np.float32)
            valid = np.zeros((len(idx), len(pushes)), dtype=bool)
            touched = np.zeros((len(idx), len(pushes)), dtype=bool)
            for p, i in enumerate(idx):
                for j, (angle, length) in enumerate(pushes):
                    world.set_object_pose(start)
                    a, c, e = push_points(start, points[i], normals[i], float(angle), length,
                                          world.config.pusher_radius, cfg.gap)
                    try:
                        res = world.execute_push(a, c, e)
                    except ValueError:
                        continue
                    before, after = res.pose_before, res.pose_after
                    d = world_to_object(before, after[:2])
                    motion[p, j] = (*d, float(wrap_angle(after[2] - before[2])))
                    valid[p, j], touched[p, j] = True, bool(res.touched)
            records.append(dict(
                object=name, points=points[idx], normals=normals[idx], motion=motion,
                valid=valid, touched=touched, com=np.asarray(spec.com), mass=spec.mass,
                friction_table=spec.friction_table, friction_pusher=spec.friction_pusher,
                l_guess=spec.limit_surface_guess(), theta0=theta0, outline_points=points,
                outline_normals=normals))
    finally:
        if world is not None:
            world.close()
    return _stack(records)


def _stack(records: list[dict[str, Any]]) -> dict[str, NDArray[Any]]:
    out: dict[str, NDArray[Any]] = {}
    for key in ("points", "normals", "motion", "valid", "touched", "com", "mass",
                "friction_table", "friction_pusher", "l_guess", "theta0"):
        out[key] = np.stack([np.asarray(r[key]) for r in records])
    out["object"] = np.array([r["object"] for r in records])
    out["outline_points"] = np.concatenate([r["outline_points"] for r in records])
    out["outline_normals"] = np.concatenate([r["outline_normals"] for r in records])
    out["outline_offsets"] = np.cumsum([0] + [len(r["outline_points"]) for r in records])
    return out


def shard_path(out: Path, index: int) -> Path:
    return out / f"shard_{index:05d}.npz"


def generate(cfg: DataConfig, out: Path, progress: bool = True) -> None:
    """Write every missing shard of ``cfg`` into ``out`` (resumable) and ``meta.json``.

    Raises
    ------
    ValueError
        If ``out`` holds a data set of another configuration.
    """
    out.mkdir(parents=True, exist_ok=True)
    meta_path = out / "meta.json"
    meta = {"format_version": FORMAT_VERSION, "config": dataclasses.asdict(cfg),
            "objects": list(_objects(cfg.test))}
    if meta_path.exists() and json.loads(meta_path.read_text()) != meta:
        raise ValueError(f"out: {out} holds a data set of another configuration; choose "
                         "another directory")
    meta_path.write_text(json.dumps(meta, indent=2))
    todo = [k for k in range(cfg.n_shards) if not shard_path(out, k).exists()]
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pushbot_affordance_data_") as tmp:
        for n, k in enumerate(todo, 1):
            arrays = generate_shard(cfg, k, Path(tmp))
            part = shard_path(out, k).with_suffix(".tmp.npz")
            np.savez_compressed(part, **arrays)
            part.replace(shard_path(out, k))
            if progress:
                rate = (time.perf_counter() - t0) / n
                print(f"shard {k} done ({n}/{len(todo)}; {rate:.0f} s per shard, "
                      f"{rate * (len(todo) - n) / 60:.1f} min left)", flush=True)


def load(directory: Path) -> dict[str, NDArray[Any]]:
    """All shards of a data set concatenated (outline offsets rebased)."""
    files = sorted(Path(directory).glob("shard_*.npz"))
    if not files:
        raise ValueError(f"directory: no shard_*.npz in {directory}")
    parts = [dict(np.load(f)) for f in files]
    out: dict[str, NDArray[Any]] = {}
    for key in parts[0]:
        if key == "outline_offsets":
            base, offs = 0, []
            for p in parts:
                offs.append(p[key][:-1] + base)
                base += int(p[key][-1])
            out[key] = np.concatenate([*offs, [base]])
        else:
            out[key] = np.concatenate([p[key] for p in parts])
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot data affordances``."""
    parser.add_argument("--n", type=int, default=DataConfig.n_samples,
                        help="object samples (20 contact points x 10 pushes each); a training "
                             f"set needs at least {MIN_TRAINING_SAMPLES} (one is held out)")
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--seed", type=int, default=0, help="seed of the data set")
    parser.add_argument("--shard-size", type=int, default=DataConfig.shard_size,
                        help="object samples per .npz shard (the last one may be shorter)")
    parser.add_argument("--test", action="store_true",
                        help="held-out test objects only (tri1, butter, hex)")


def run(args: argparse.Namespace) -> int:
    """Entry point of ``pushbot data affordances``.

    Raises
    ------
    ValueError
        If ``--n`` is below :data:`MIN_TRAINING_SAMPLES` for a training set, the
        configuration is invalid, or ``--out`` holds another configuration.
    """
    if not args.test and args.n < MIN_TRAINING_SAMPLES:
        raise ValueError(f"--n {args.n}: a training set needs at least {MIN_TRAINING_SAMPLES} "
                         "samples (one is held out for validation)")
    cfg = DataConfig(n_samples=args.n, seed=args.seed, shard_size=args.shard_size,
                     test=args.test)
    generate(cfg, args.out)
    print(f"wrote {cfg.n_samples} samples in {cfg.n_shards} shard(s) to {args.out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m pushbot.experiments.affordance_data``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
