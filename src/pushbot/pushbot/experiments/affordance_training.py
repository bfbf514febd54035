"""Train the learned affordance model (``pushbot train affordances``).

Reads a data set of ``pushbot data affordances`` (:mod:`pushbot.experiments.affordance_data`),
trains :class:`push_core.learned.AffordanceNet` on the CPU (one intra-op thread, seeded),
evaluates it against pybullet on a held-out test set (``pushbot data affordances --test``: tri1,
butter, hex) next to the analytical model, and writes the weights plus a model card
(``MODEL_CARD.md`` beside them) under ``out/train/affordances/`` (:data:`OUT_DIR`, or
``--out``). ``--install`` writes them over the bundled ``push_planner/models/affordances.pt``
and its ``MODEL_CARD.md`` instead, the only way the committed weights and card change; it needs
``--test-data`` so that the card keeps its metrics table (refused before training otherwise).

Training: every sample appears in ``rotations`` rotated copies of its object frame (random
angles, seeded) and their mirror images (y -> -y: the outline order reverses, push angles and
the tangential motion and rotation change sign), so the network sees the physics' symmetries.
10 % of the samples (by sample, seeded) are held out for validation; the weights of the epoch
with the lowest validation loss are kept. Loss: smooth L1 (beta = 1) on the scaled contact-frame
targets (:func:`push_core.learned.contact_frame_targets`: cm and units of 5 deg, so 1 cm of
error weighs as much as 5 deg, close to the planner's lambda = 2 mm/deg), over the pushes the
world executed. AdamW, cosine learning-rate decay, stops at ``--epochs`` or ``--minutes``.

Usage::

    pushbot train affordances --data out/affordance_data/train \\
        --test-data out/affordance_data/test [--minutes 45] [--out PATH | --install]
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import platform
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["add_arguments", "evaluate", "run"]

#: Where a training run writes by default (relative to the working directory).
OUT_DIR = Path("out/train/affordances")

#: Representative push index after mirroring (angles 0, 30, -30, 60, -60 per length).
MIRROR_PUSH = np.array([0, 2, 1, 4, 3, 5, 7, 6, 9, 8])


def _variants(data: dict[str, Any], rotations: int, rng: np.random.Generator
              ) -> dict[str, NDArray[Any]]:
    """Shape encodings, inputs and targets of every sample x rotation x (plain, mirrored)."""
    from push_core.learned import contact_frame_targets, shape_encoding

    offs = data["outline_offsets"]
    n = len(data["com"])
    enc, com, pts, nrm, tgt, val = [], [], [], [], [], []
    targets = contact_frame_targets(data["points"], data["normals"], data["com"],
                                    np.nan_to_num(data["motion"].astype(np.float64)))
    for s in range(n):
        op = data["outline_points"][offs[s]:offs[s + 1]]
        on = data["outline_normals"][offs[s]:offs[s + 1]]
        for r in range(rotations):
            phi = 0.0 if r == 0 else float(rng.uniform(-math.pi, math.pi))
            c, si = math.cos(phi), math.sin(phi)
            rot = np.array([[c, -si], [si, c]])
            for mirror in (False, True):
                m = np.array([1.0, -1.0]) if mirror else np.ones(2)
                o_p, o_n = (op @ rot.T) * m, (on @ rot.T) * m
                p, q = (data["points"][s] @ rot.T) * m, (data["normals"][s] @ rot.T) * m
                cc = (data["com"][s] @ rot.T) * m
                t, v = targets[s], data["valid"][s]
                if mirror:
                    o_p, o_n = o_p[::-1], o_n[::-1]
                    t = t[:, MIRROR_PUSH] * np.array([1.0, -1.0, -1.0])
                    v = v[:, MIRROR_PUSH]
                e = shape_encoding(o_p, o_n)
                enc.append(np.concatenate([e[:2].astype(np.uint8),
                                           np.round(e[2:] * 127).astype(np.int8).view(np.uint8)
                                           ]))
                com.append(cc)
                pts.append(p)
                nrm.append(q)
                tgt.append(t)
                val.append(v)
    shape = (n, rotations * 2)
    return {"encoding": np.stack(enc).reshape(*shape, 4, *enc[0].shape[1:]),
            "com": np.stack(com).reshape(*shape, 2).astype(np.float32),
            "points": np.stack(pts).reshape(*shape, *pts[0].shape).astype(np.float32),
            "normals": np.stack(nrm).reshape(*shape, *nrm[0].shape).astype(np.float32),
            "targets": np.stack(tgt).reshape(*shape, *tgt[0].shape).astype(np.float32),
            "valid": np.stack(val).reshape(*shape, *val[0].shape)}


def _decode(enc: NDArray[np.uint8]) -> Any:
    import torch

    t = torch.from_numpy(enc)
    return torch.cat([t[:, :2].float(), t[:, 2:].view(torch.int8).float() / 127.0], 1)


def _batch(v: dict[str, NDArray[Any]], samples: NDArray[np.intp], variant: NDArray[np.intp]
           ) -> tuple[Any, ...]:
    import torch

    enc = _decode(v["encoding"][samples, variant])
    return (enc, *(torch.from_numpy(v[k][samples, variant])
                   for k in ("com", "points", "normals", "targets", "valid")))


def _loss(net: Any, batch: tuple[Any, ...]) -> Any:
    import torch.nn.functional as F  # noqa: N812

    enc, com, pts, nrm, tgt, valid = batch
    pred = net(enc, com, pts, nrm)
    err = F.smooth_l1_loss(pred, tgt, reduction="none", beta=1.0).sum(-1)
    return (err * valid).sum() / valid.sum().clamp(min=1)


def evaluate(model: Any, data: dict[str, Any]) -> dict[str, Any]:
    """Errors of ``lrn`` (``model``), ``ana`` and "no motion" against pybullet on a data set.

    ``ana`` is :func:`push_core.affordances.analytical_affordances` with the true COM, the
    simulated pusher friction and ``l`` of uniform pressure (``l_guess``): what the planner uses
    with ground-truth state. Errors of the origin motion (object frame): translation in mm and
    rotation in deg, over the pushes the world executed, per object and push length.
    """
    from push_core.affordances import analytical_affordances

    rows: dict[str, dict[str, list[NDArray[np.float64]]]] = {}
    for s in range(len(data["com"])):
        obj = str(data["object"][s])
        p, n, com = data["points"][s], data["normals"][s], data["com"][s]
        truth = data["motion"][s].astype(np.float64)
        valid = data["valid"][s]
        preds = {"lrn": model(p, n, com),
                 "ana": analytical_affordances(p, n, com, float(data["l_guess"][s]),
                                               float(data["friction_pusher"][s])),
                 "no motion": np.zeros_like(truth)}
        for name, pred in preds.items():
            d = pred - truth
            trans = 1e3 * np.hypot(d[..., 0], d[..., 1])
            rot = np.degrees(np.abs(np.angle(np.exp(1j * d[..., 2]))))
            for length, cols in (("1 cm", slice(0, 5)), ("5 cm", slice(5, 10))):
                key = f"{obj}|{length}|{name}"
                entry = rows.setdefault(key, {"t": [], "r": []})
                entry["t"].append(trans[:, cols][valid[:, cols]])
                entry["r"].append(rot[:, cols][valid[:, cols]])
    out: dict[str, Any] = {}
    for key, entry in rows.items():
        t, r = np.concatenate(entry["t"]), np.concatenate(entry["r"])
        out[key] = {"n": int(t.size), "trans_median_mm": float(np.median(t)),
                    "trans_mean_mm": float(np.mean(t)), "rot_median_deg": float(np.median(r)),
                    "rot_mean_deg": float(np.mean(r))}
    return out


def metrics_table(metrics: dict[str, Any]) -> str:
    """Markdown table of :func:`evaluate`'s output."""
    lines = ["| object | push length | predictor | pushes | translation error mm (median / "
             "mean) | rotation error deg (median / mean) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for key, m in metrics.items():
        obj, length, name = key.split("|")
        lines.append(f"| {obj} | {length} | {name} | {m['n']} | {m['trans_median_mm']:.1f} / "
                     f"{m['trans_mean_mm']:.1f} | {m['rot_median_deg']:.1f} / "
                     f"{m['rot_mean_deg']:.1f} |")
    return "\n".join(lines)


def installed_weights() -> Path:
    """Path of the bundled weights the planner loads (``push_planner/models/affordances.pt``)."""
    from push_planner.models import default_weights

    return default_weights()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot train affordances``."""
    parser.add_argument("--data", type=Path, required=True,
                        help="training data (pushbot data affordances --out DIR), at least 2 "
                             "samples")
    parser.add_argument("--test-data", type=Path, default=None,
                        help="held-out data (pushbot data affordances --test --out DIR) for the "
                             "model card's metrics table")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=OUT_DIR / "affordances.pt",
                       help="weights file; MODEL_CARD.md is written beside it")
    where.add_argument("--install", action="store_true",
                       help="write the weights and MODEL_CARD.md over the bundled ones "
                            "(push_planner/models), which the planner loads; needs --test-data")
    parser.add_argument("--minutes", type=float, default=45.0,
                        help="training time budget, minutes")
    parser.add_argument("--epochs", type=int, default=300, help="most epochs")
    parser.add_argument("--batch", type=int, default=16, help="samples per batch")
    parser.add_argument("--lr", type=float, default=2e-3, help="peak learning rate (AdamW)")
    parser.add_argument("--rotations", type=int, default=8,
                        help="rotated copies of every sample (each also mirrored)")
    parser.add_argument("--channels", type=int, nargs=3, default=[16, 32, 32],
                        help="channels of the three shape-feature convolutions")
    parser.add_argument("--hidden", type=int, default=128, help="units of the head's layers")
    parser.add_argument("--seed", type=int, default=0, help="seed")


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse bad options before anything is loaded or trained (``ValueError``)."""
    if args.install and args.test_data is None:
        raise ValueError("--install needs --test-data: the bundled model card keeps its metrics "
                         "table (pushbot data affordances --test --out DIR)")
    for name in ("epochs", "batch", "rotations", "hidden"):
        if getattr(args, name) < 1:
            raise ValueError(f"--{name} {getattr(args, name)}: expected an integer >= 1")
    if min(args.channels) < 1:
        raise ValueError(f"--channels {args.channels}: expected integers >= 1")
    if not (math.isfinite(args.minutes) and args.minutes > 0):
        raise ValueError(f"--minutes {args.minutes}: expected a positive number")
    if not (math.isfinite(args.lr) and args.lr > 0):
        raise ValueError(f"--lr {args.lr}: expected a positive number")
    for name in ("data", "test_data"):
        path = getattr(args, name)
        if path is not None and not (Path(path) / "meta.json").is_file():
            raise ValueError(f"--{name.replace('_', '-')} {path}: not a data set of `pushbot "
                             "data affordances` (no meta.json)")


def run(args: argparse.Namespace) -> int:
    """Entry point of ``pushbot train affordances``.

    Raises
    ------
    ValueError
        Before training: ``--install`` without ``--test-data``, an option out of range, a
        folder that is not a data set, or fewer than 2 samples.
    """
    _check_arguments(args)
    import torch

    from push_core.learned import FORMAT_VERSION, AffordanceNet, LearnedAffordances
    from pushbot.experiments.affordance_data import load

    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    data = load(args.data)
    v = _variants(data, args.rotations, rng)
    n, n_var = v["com"].shape[:2]
    if n < 2:
        raise ValueError(f"data: need at least 2 samples (one for validation), got {n}")
    order = rng.permutation(n)
    n_val = max(1, n // 10)
    val_idx, train_idx = order[:n_val], order[n_val:]
    print(f"{n} samples ({len(train_idx)} train, {n_val} validation) x {n_var} variants, "
          f"{int(data['valid'].sum())} executed pushes; encodings in "
          f"{time.perf_counter() - t0:.0f} s", flush=True)

    cfg = {"channels": [int(c) for c in args.channels], "hidden": int(args.hidden),
           "grid": 64, "resolution": 0.004}
    net = AffordanceNet(channels=tuple(cfg["channels"]), hidden=cfg["hidden"])
    opt = torch.optim.AdamW(net.parameters(), lr=args.lr, weight_decay=1e-4)
    steps_per_epoch = math.ceil(len(train_idx) / args.batch)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, args.epochs * steps_per_epoch)
    val_batch = _batch(v, val_idx, np.zeros(n_val, dtype=np.intp))
    best, best_state, history = math.inf, None, []
    t_train, epoch = time.perf_counter(), 0
    for epoch in range(1, args.epochs + 1):
        net.train()
        perm = rng.permutation(train_idx)
        total = 0.0
        for i in range(0, len(perm), args.batch):
            idx = perm[i:i + args.batch]
            loss = _loss(net, _batch(v, idx, rng.integers(n_var, size=len(idx))))
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += loss.item() * len(idx)
        net.eval()
        with torch.no_grad():
            val = float(_loss(net, val_batch))
        history.append((epoch, total / len(perm), val))
        if val < best:
            best = val
            best_state = {k: t.clone() for k, t in net.state_dict().items()}
        minutes = (time.perf_counter() - t_train) / 60.0
        print(f"epoch {epoch}: train {total / len(perm):.4f}, validation {val:.4f} "
              f"(best {best:.4f}), {minutes:.1f} min", flush=True)
        if minutes * (epoch + 1) / epoch > args.minutes:
            break
    net.load_state_dict(best_state)
    train_minutes = (time.perf_counter() - t_train) / 60.0

    metrics = None
    if args.test_data is not None:
        metrics = evaluate(LearnedAffordances(net), load(args.test_data))
        print(metrics_table(metrics))
    out = installed_weights() if args.install else args.out
    command = "pushbot train affordances " + " ".join(sys.argv[3:] if sys.argv[1:3] == [
        "train", "affordances"] else sys.argv[1:])
    meta = {
        "date": datetime.datetime.now(datetime.UTC).date().isoformat(),
        "command": command.strip(), "seed": args.seed, "data": str(args.data),
        "data_meta": json.loads((Path(args.data) / "meta.json").read_text()),
        "test_data": None if args.test_data is None else str(args.test_data),
        "samples": int(n), "validation_samples": int(n_val),
        "executed_pushes": int(data["valid"].sum()), "variants_per_sample": int(n_var),
        "epochs": epoch, "best_validation_loss": best, "train_minutes": round(train_minutes, 1),
        "history": history, "test_metrics": metrics,
        "machine": f"{platform.node()}, Python {platform.python_version()}, "
                   f"torch {torch.__version__}, 1 thread",
        "lr": args.lr, "batch": args.batch, "rotations": args.rotations,
        "channels": cfg["channels"], "hidden": cfg["hidden"],
        "parameters": int(sum(p.numel() for p in net.parameters())),
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    torch.save({"format_version": FORMAT_VERSION, "config": cfg, "state_dict": net.state_dict(),
                "meta": meta}, out)
    (out.parent / "MODEL_CARD.md").write_text(model_card(meta, out.name))
    print(f"wrote {out} ({out.stat().st_size / 1e6:.2f} MB) and {out.parent / 'MODEL_CARD.md'}")
    return 0


def model_card(meta: dict[str, Any], weights_name: str) -> str:
    """The model card (markdown) of a trained model from its metadata."""
    d = meta["data_meta"]["config"]
    hist = meta["history"]
    lines = [
        "# Model card: learned affordances (`lrn`)",
        "",
        f"Weights: `{weights_name}` (`push_core.learned.load_affordance_model`). Written by "
        "`pushbot.experiments.affordance_training` on " + meta["date"] + "; do not edit by hand.",
        "",
        "## Model",
        "`push_core.learned.AffordanceNet`: 64 x 64 shape encoding (4 mm pixels; occupancy, "
        "outline, outward normals) + 2 COM channels -> 3-layer CNN with max-pooling ("
        + "/".join(str(c) for c in meta["channels"]) + " channels), features sampled at each "
        "contact point + global max -> 3-layer head without pooling ("
        f"{meta['hidden']}/{meta['hidden']}/3) per point x representative push; "
        f"{meta['parameters']} parameters; predicts the COM motion "
        "in the contact frame and the rotation, converted to the object-frame origin motion. "
        "Does not use l or m.",
        "",
        "## Data",
        f"- `pushbot data affordances` (module `pushbot.experiments.affordance_data`), seed "
        f"{d['seed']}: {meta['samples']} object samples ({meta['validation_samples']} held "
        f"out for validation), {d['points_per_sample']} contact points x 10 representative "
        f"pushes each, {meta['executed_pushes']} executed pushes; objects: library objects "
        f"except tri1, butter, hex (p = {d['library_fraction']}) and procedural shapes "
        "(pushbot.experiments.perception_data.random_shape); randomised mass, COM, frictions "
        "(sim_bridge.world); pybullet default physics, 20 mm/s.",
        f"- Training: {meta['variants_per_sample']} variants per sample ({meta['rotations']} "
        f"rotations x mirror), AdamW lr {meta['lr']}, batch {meta['batch']} samples, "
        f"{meta['epochs']} epochs in {meta['train_minutes']} min on {meta['machine']}; best "
        f"validation loss {meta['best_validation_loss']:.4f} (smooth L1 on cm / 5 deg units).",
        f"- Command: `{meta['command']}` (seed {meta['seed']}).",
        f"- Validation loss by epoch (first, best, last): {hist[0][2]:.4f}, "
        f"{min(h[2] for h in hist):.4f}, {hist[-1][2]:.4f}.",
        "",
        "## Metrics against pybullet (held-out objects)",
    ]
    if meta["test_metrics"]:
        lines += ["", f"Test data: `{meta['test_data']}` (tri1, butter, hex, randomised "
                  "physics). ana = analytical one-step model with the true COM and pusher "
                  "friction and l of uniform pressure.", "", metrics_table(meta["test_metrics"])]
    else:
        lines += ["", "Not evaluated (no --test-data)."]
    lines += ["", "## Limits", "- Trained in simulation only (pybullet); the real robot and "
              "perception outlines differ.", "- Outlines must fit the 25.6 cm image (objects up "
              "to about 24 cm across)."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m pushbot.experiments.affordance_training``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
