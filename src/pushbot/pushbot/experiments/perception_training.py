"""Training of the segmentation CNN (:mod:`push_perception.model`) on generated data.

``pushbot train segmentation --data DIR`` trains both stages jointly on a data set written by
``pushbot data perception`` and saves the weights, the report (``.json``) and a model card
(``.md``) under ``out/train/segmentation/`` (:data:`OUT_DIR`, or ``--out``); ``--install``
writes them over the bundled ones in ``push_perception/models`` instead, the only way the
committed weights and card change (the card always holds the validation metrics). The data set
needs at least two shards (the last is held out). CPU only, one intra-op
thread by default (the machine is shared); the default schedule takes about 25 minutes on the
project's 2-core machine.

Data preparation (cached under ``DIR/prepared_v<N>/`` as ``.npy`` files, reused while the data
and this version do not change): for every frame the height map (world z of each pixel, from
depth, K and the extrinsics), the coarse input (colour and height downscaled by
``coarse_factor``, ``cv2.INTER_AREA``), the coarse target (the mask's area fraction in each
coarse output cell), and a ``WINDOW`` x ``WINDOW`` full-resolution window centred on the
object's bounding box (colour, height, mask; a random window when the frame is empty).

Training (one step = one batch): the coarse net sees the whole downscaled frames; the fine net
sees a random ``CROP`` x ``CROP`` sub-window of each stored window with the coarse logits
resampled into it (detached: each stage learns its own job). Loss: binary cross-entropy
(soft targets for the coarse stage) plus a soft Dice term for the fine stage. Adam with cosine
learning-rate decay; colour augmentation (per-channel gain and offset, same for both stages).
The last shard of the data set is held out for validation: the full two-stage
:class:`~push_perception.model.Segmenter` runs on its full frames and reports mask IoU.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import time
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pushbot.experiments.machine import machine_info

__all__ = ["TrainConfig", "add_arguments", "evaluate_iou", "prepare", "run", "train"]

#: Side of the stored full-resolution window around the object, px.
WINDOW = 200
#: Side of the random sub-window the fine stage is trained on, px.
CROP = 160
#: File name of the weights (as ``push_perception.model.DEFAULT_WEIGHTS``).
DEFAULT_WEIGHTS = "segmentation.pt"
#: Version of the prepared cache (bump when ``prepare`` changes).
PREPARED_VERSION = 1
#: Where a training run writes by default (relative to the working directory).
OUT_DIR = Path("out/train/segmentation")


@dataclass(frozen=True)
class TrainConfig:
    """Hyper-parameters of a training run.

    Attributes
    ----------
    steps : int
        Optimiser steps.
    batch : int
        Frames per step.
    lr : float
        Peak learning rate of Adam (cosine decay to 1 % of it).
    weight_decay : float
        L2 penalty of Adam.
    seed : int
        Seed of initialisation, batch order, crops and augmentation.
    threads : int
        torch intra-op threads.
    val_shards : int
        Number of final shards held out for validation.
    init : str
        ``""`` (random initialisation), ``"bundled"`` (fine-tune the bundled weights) or the
        path of a checkpoint to start from.
    """

    steps: int = 3000
    batch: int = 12
    lr: float = 3e-3
    weight_decay: float = 1e-4
    seed: int = 0
    threads: int = 1
    val_shards: int = 1
    init: str = ""


#: The schedule of a fine-tuning run (``--init``) where the options do not say otherwise.
FINE_TUNE = TrainConfig(steps=300, lr=1e-3)


# --------------------------------------------------------------------------------------------
# Data preparation
# --------------------------------------------------------------------------------------------
def _shards(data: Path) -> list[Path]:
    shards = sorted(p for p in Path(data).glob("shard_*.npz") if not p.name.endswith(".tmp.npz"))
    if not shards:
        raise ValueError(f"{data}: no shard_*.npz files (run pushbot data perception first)")
    return shards


def _check_shards(data: Path, cfg: TrainConfig) -> list[Path]:
    """The shards of ``data``, refused unless one is left to train on after the held-out ones."""
    shards = _shards(data)
    if len(shards) <= cfg.val_shards:
        raise ValueError(f"{data}: {len(shards)} shard(s); training needs at least "
                         f"{cfg.val_shards + 1} (the last {cfg.val_shards} held out for "
                         "validation): regenerate it with `pushbot data perception` (2 frames "
                         "or more, without a --shard-size as large as --n)")
    return shards


def initial_net(init: str) -> Any:
    """The :class:`~push_perception.model.SegmentationNet` of ``init`` (``"bundled"`` or a
    checkpoint path) in training mode; ``ValueError`` when it cannot be read."""
    from push_perception.model import load_net

    return load_net(installed_weights() if init == "bundled" else Path(init)).train()


def installed_weights() -> Path:
    """Path of the bundled weights the segmentation node loads
    (``push_perception/models/segmentation.pt``)."""
    from importlib import resources

    return Path(str(resources.files("push_perception").joinpath("models", DEFAULT_WEIGHTS)))


def prepare(data: Path, shards: list[Path], seed: int = 0) -> dict[str, NDArray[Any]]:
    """Training arrays of ``shards`` (cached; see the module docstring).

    Returns
    -------
    dict
        ``small_rgb`` (N, h, w, 3) uint8, ``small_height`` (N, h, w) float16 (m),
        ``coarse_target`` (N, h/2, w/2) uint8 (area fraction x 255), ``win_rgb``
        (N, WINDOW, WINDOW, 3) uint8, ``win_height`` (N, WINDOW, WINDOW) float16 (m, NaN = no
        depth), ``win_mask`` (N, WINDOW, WINDOW) bool, ``win_origin`` (N, 2) int (u0, v0) and
        ``image_size`` (N, 2) int (W, H).
    """
    import cv2

    from push_perception.model import HeightMap, coarse_factor
    from pushbot.experiments.perception_data import decode_depth

    key = ",".join(p.name for p in shards).encode()
    cache = Path(data) / f"prepared_v{PREPARED_VERSION}" / f"{len(shards)}_{zlib.crc32(key):08x}"
    names = ("small_rgb", "small_height", "coarse_target", "win_rgb", "win_height", "win_mask",
             "win_origin", "image_size")
    if all((cache / f"{n}.npy").exists() for n in names):
        return {n: np.load(cache / f"{n}.npy") for n in names}
    rng = np.random.default_rng(seed)
    heights = HeightMap()
    out: dict[str, list[NDArray[Any]]] = {n: [] for n in names}
    from tqdm import tqdm

    for path in tqdm(shards, desc="preparing", unit="shard"):
        with np.load(path) as z:
            arrays = {k: z[k] for k in ("rgb", "depth", "mask", "camera_matrix",
                                         "T_world_camera")}
        for i in range(len(arrays["rgb"])):
            rgb, mask = arrays["rgb"][i], arrays["mask"][i]
            height = heights(decode_depth(arrays["depth"][i]), arrays["camera_matrix"][i],
                             arrays["T_world_camera"][i])
            h, w = mask.shape
            s = coarse_factor(w)
            small = (round(w / s), round(h / s))
            out["small_rgb"].append(cv2.resize(rgb, small, interpolation=cv2.INTER_AREA))
            out["small_height"].append(cv2.resize(np.nan_to_num(height, nan=0.0), small,
                                                  interpolation=cv2.INTER_AREA)
                                       .astype(np.float16))
            target = cv2.resize(mask.astype(np.float32), ((small[0] + 1) // 2,
                                                          (small[1] + 1) // 2),
                                interpolation=cv2.INTER_AREA)
            out["coarse_target"].append(np.round(255 * target).astype(np.uint8))
            if mask.any():
                v, u = np.nonzero(mask)
                cu, cv = 0.5 * (u.min() + u.max()), 0.5 * (v.min() + v.max())
            else:
                cu, cv = rng.uniform(0, w), rng.uniform(0, h)
            u0 = int(np.clip(round(cu - WINDOW / 2), 0, w - WINDOW))
            v0 = int(np.clip(round(cv - WINDOW / 2), 0, h - WINDOW))
            win = (slice(v0, v0 + WINDOW), slice(u0, u0 + WINDOW))
            out["win_rgb"].append(rgb[win])
            out["win_height"].append(height[win].astype(np.float16))
            out["win_mask"].append(mask[win])
            out["win_origin"].append(np.array([u0, v0]))
            out["image_size"].append(np.array([w, h]))
    result = {n: np.stack(v) for n, v in out.items()}
    cache.mkdir(parents=True, exist_ok=True)
    for n, v in result.items():
        np.save(cache / f"{n}.npy", v)
    return result


# --------------------------------------------------------------------------------------------
# Training
# --------------------------------------------------------------------------------------------
def train(data: Path, cfg: TrainConfig, progress: bool = True) -> tuple[Any, dict[str, Any]]:
    """Train a :class:`~push_perception.model.SegmentationNet`; returns it and a report.

    The report holds the configuration, the data set's meta data, the number of training and
    validation frames, the loss curve (every 50 steps), the wall time and the validation
    metrics of :func:`evaluate_iou`.
    """
    import torch
    import torch.nn.functional as F

    from push_perception.model import HEIGHT_SCALE, SegmentationNet, Segmenter, crop_grid

    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    shards = _check_shards(data, cfg)
    train_shards, val_shards = shards[:-cfg.val_shards], shards[-cfg.val_shards:]
    prepare_started = time.monotonic()
    arrays = prepare(data, train_shards, cfg.seed)
    prepare_minutes = (time.monotonic() - prepare_started) / 60.0
    n = len(arrays["small_rgb"])
    rng = np.random.default_rng(cfg.seed)
    net = SegmentationNet()
    if cfg.init:
        net = initial_net(cfg.init)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.LambdaLR(
        opt, lambda k: 0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * min(k, cfg.steps) / cfg.steps)))
    small_rgb = torch.from_numpy(arrays["small_rgb"])
    small_h = torch.from_numpy(arrays["small_height"])
    target_c = torch.from_numpy(arrays["coarse_target"])
    win_rgb = torch.from_numpy(arrays["win_rgb"])
    win_h = torch.from_numpy(arrays["win_height"])
    win_m = torch.from_numpy(arrays["win_mask"])
    curve: list[tuple[int, float, float]] = []
    started = time.monotonic()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=cfg.steps, desc="training", unit="step")
    net.train()
    run_c = run_f = 0.0
    for step in range(cfg.steps):
        idx = torch.from_numpy(rng.integers(0, n, cfg.batch))
        gain = torch.from_numpy(rng.uniform(0.8, 1.2, (cfg.batch, 3, 1, 1))).float()
        shift = torch.from_numpy(rng.uniform(-0.08, 0.08, (cfg.batch, 1, 1, 1))).float()

        coarse = net.coarse(_inputs(small_rgb[idx], small_h[idx], gain, shift, HEIGHT_SCALE))
        loss_c = F.binary_cross_entropy_with_logits(coarse[:, 0], target_c[idx].float() / 255.0)
        offs = rng.integers(0, WINDOW - CROP + 1, (cfg.batch, 2))
        rows = [slice(o[1], o[1] + CROP) for o in offs]
        cols = [slice(o[0], o[0] + CROP) for o in offs]
        crop_rgb = torch.stack([win_rgb[i, r, c] for i, r, c in zip(idx, rows, cols,
                                                                       strict=True)])
        crop_h = torch.stack([win_h[i, r, c] for i, r, c in zip(idx, rows, cols, strict=True)])
        crop_m = torch.stack([win_m[i, r, c] for i, r, c in zip(idx, rows, cols, strict=True)])
        grids = []
        for b, i in enumerate(idx.tolist()):
            u0 = int(arrays["win_origin"][i, 0] + offs[b, 0])
            v0 = int(arrays["win_origin"][i, 1] + offs[b, 1])
            grids.append(crop_grid((u0, v0, u0 + CROP, v0 + CROP),
                                   tuple(int(v) for v in arrays["image_size"][i])))
        sampled = F.grid_sample(coarse.detach(), torch.cat(grids), mode="bilinear",
                                padding_mode="border", align_corners=False)
        fine = net.fine(torch.cat([_inputs(crop_rgb, crop_h, gain, shift, HEIGHT_SCALE), sampled],
                                   dim=1))[:, 0]
        target_f = crop_m.float()
        prob = torch.sigmoid(fine)
        dice = 1 - (2 * (prob * target_f).sum((1, 2)) + 1) / (prob.sum((1, 2))
                                                              + target_f.sum((1, 2)) + 1)
        loss_f = F.binary_cross_entropy_with_logits(fine, target_f) + 0.5 * dice.mean()
        loss = loss_c + loss_f
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        sched.step()
        run_c += loss_c.item()
        run_f += loss_f.item()
        if (step + 1) % 50 == 0:
            curve.append((step + 1, run_c / 50, run_f / 50))
            if bar is not None:
                bar.set_postfix(coarse=f"{run_c / 50:.4f}", fine=f"{run_f / 50:.4f}")
            run_c = run_f = 0.0
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    minutes = (time.monotonic() - started) / 60.0
    net.eval()
    metrics = evaluate_iou(Segmenter(net), val_shards)
    meta = json.loads((Path(data) / "meta.json").read_text()) \
        if (Path(data) / "meta.json").exists() else {}
    report = {"train_config": asdict(cfg), "data": str(data), "data_meta": meta,
              "train_frames": n, "val_shards": [p.name for p in val_shards],
              "train_minutes": round(minutes, 1), "prepare_minutes": round(prepare_minutes, 1),
              "loss_curve": curve,
              "validation": metrics,
              "parameters": sum(p.numel() for p in net.parameters()),
              "date": datetime.datetime.now(datetime.UTC).date().isoformat(),
              "machine": machine_info()}
    return net, report


def _inputs(rgb: Any, height: Any, gain: Any, shift: Any, height_scale: float) -> Any:
    """Network input (B, 4, h, w) from uint8 colour (B, h, w, 3) and float16 height (B, h, w)
    (metres), with the colour augmentation ``gain`` (B, 3, 1, 1) and ``shift`` (B, 1, 1, 1);
    the same normalisation as :func:`push_perception.model.normalise_inputs`."""
    import torch

    colour = (rgb.permute(0, 3, 1, 2).float() / 255.0 - 0.5) * gain + shift
    h = torch.nan_to_num(height.float() / height_scale, nan=0.0).clamp(-1.0, 4.0)
    return torch.cat([colour, h[:, None]], dim=1)


def evaluate_iou(segmenter: Any, shards: list[Path]) -> dict[str, float]:
    """Mask IoU of ``segmenter`` on every frame of ``shards`` (full frames, full pipeline).

    Frames whose true mask is empty count as correct when the prediction is empty too (IoU
    1) and wrong otherwise (IoU 0).

    Returns
    -------
    dict
        ``frames``, ``iou_median``, ``iou_mean``, ``iou_p10`` and ``empty_correct`` (the
        fraction of empty frames predicted empty; NaN without empty frames).
    """
    from pushbot.experiments.perception_data import decode_depth

    ious, empties = [], []
    for path in shards:
        with np.load(path) as z:
            arrays = {k: z[k] for k in ("rgb", "depth", "mask", "camera_matrix",
                                         "T_world_camera")}
        for i in range(len(arrays["rgb"])):
            truth = arrays["mask"][i]
            pred = segmenter(arrays["rgb"][i], decode_depth(arrays["depth"][i]),
                             arrays["camera_matrix"][i], arrays["T_world_camera"][i]).mask
            union = np.count_nonzero(truth | pred)
            iou = 1.0 if union == 0 else np.count_nonzero(truth & pred) / union
            ious.append(iou)
            if not truth.any():
                empties.append(not pred.any())
    a = np.array(ious)
    return {"frames": len(a), "iou_median": float(np.median(a)), "iou_mean": float(a.mean()),
            "iou_p10": float(np.quantile(a, 0.1)),
            "empty_correct": float(np.mean(empties)) if empties else float("nan")}


def save(net: Any, report: dict[str, Any], out: Path, command: str) -> None:
    """Write the weights to ``out`` (a ``.pt`` with ``state_dict`` and ``report``), the report
    as JSON (``out`` with suffix ``.json``) and a model card (suffix ``.md``) next to it."""
    import torch

    out.parent.mkdir(parents=True, exist_ok=True)
    report = {**report, "command": command}
    torch.save({"state_dict": net.state_dict(), "report": report}, out)
    out.with_suffix(".json").write_text(json.dumps(report, indent=2) + "\n")
    out.with_suffix(".md").write_text(model_card(report, out))


def model_card(report: dict[str, Any], weights: Path) -> str:
    """Markdown model card of a training report (data, seed, command, metrics)."""
    cfg, v = report["train_config"], report["validation"]
    data_cfg = report.get("data_meta", {}).get("config", {})
    objects = ", ".join(report.get("data_meta", {}).get("training_objects", []))
    size_kb = weights.stat().st_size / 1024 if weights.exists() else float("nan")
    if report.get("data_meta", {}).get("kind") == "site":
        return _site_card(report, weights, size_kb)
    return f"""# Segmentation CNN (`{weights.name}`)

Two-stage encoder-decoder on RGB + height above the table (`push_perception.model`): a coarse
net on the frame downscaled to 160 x 120 locates the object, a fine net refines a full-resolution
crop around it. {report["parameters"]} parameters, {size_kb:.0f} KB. Inference and preprocessing:
`push_perception.model.Segmenter`; design and accuracy: docs/design/perception.md and
docs/results/eval_perception.md and docs/results/bench_perception.md.

## Data

- generated by `pushbot data perception --n {data_cfg.get("n", "?")} --out {report["data"]}
  --seed {data_cfg.get("seed", "?")}` (`pushbot.experiments.perception_data`, format in its
  docstring):
  {data_cfg.get("width", "?")} x {data_cfg.get("height", "?")} frames rendered by the sim
  bridge's pybullet world;
- objects: the MIT training objects ({objects}) and procedurally generated shapes (convex
  polygons, ellipses, stars, blobs, L/T shapes); **tri1, butter and hex are held out**;
- random poses, mass, COM and friction; random colours, lighting and shadows in 85 % of the
  scenes; camera pose jitter; RealSense-like depth noise in half of the scenes; the pusher
  near the object in 40 % of the frames and elsewhere in 10 %; 2 % empty frames;
- training frames: {report["train_frames"]}; validation: the held-out shard(s)
  {", ".join(report["val_shards"])} (same distribution, frames never trained on).

## Training

- command: `{report["command"]}`
- seed {cfg["seed"]}, {cfg["steps"]} steps of {cfg["batch"]} frames, Adam (lr {cfg["lr"]},
  cosine decay, weight decay {cfg["weight_decay"]}), {cfg["threads"]} torch thread(s), CPU;
- wall time {report["train_minutes"]} min of training on
  {report.get("machine", "an unrecorded machine")} ({report["date"]}), after
  {report.get("prepare_minutes", "?")} min preparing the cached arrays (first run on a data set
  only).

## Metrics

Validation (full two-stage pipeline on full frames of the held-out shard): mask IoU median
{v["iou_median"]:.4f}, mean {v["iou_mean"]:.4f}, 10th percentile {v["iou_p10"]:.4f} over
{v["frames"]} frames; empty frames predicted empty: {v["empty_correct"]:.2f}.

Held-out test objects (tri1, butter, hex): `pushbot eval perception`,
docs/results/eval_perception.md.

## Limits

Trained on simulated frames of one camera model (D415-like intrinsics, oblique views 45-70
degrees down, 0.7-0.9 m) and flat, uniformly coloured objects on a uniformly coloured table;
a real camera, textured objects or clutter need new data (and probably fine-tuning).
"""


def _site_card(report: dict[str, Any], weights: Path, size_kb: float) -> str:
    """Model card of a network fine-tuned on ``pushbot data record`` site frames."""
    cfg, v, meta = report["train_config"], report["validation"], report["data_meta"]
    dropped = ", ".join(f"{k} {n}" for k, n in meta.get("dropped", {}).items())
    rule = meta.get("rule", {})
    return f"""# Segmentation CNN adapted to a site (`{weights.name}`)

The two-stage network of `push_perception.model` ({report["parameters"]} parameters,
{size_kb:.0f} KB), fine-tuned from `{cfg["init"]}` on frames recorded at the site. Load it
with segmentation_node's parameter `weights:={weights}`; the bundled default is unchanged.
Design: docs/design/site-adaptation.md.

## Data

- recorded by `pushbot data record` into {report["data"]}: {meta.get("frames", "?")} frames
  kept in {meta.get("shards", "?")} shard(s) (one per scene); labels from the depth
  segmentation, kept when consecutive frames agree (IoU >= {rule.get("min_iou", "?")}, table
  plane RMS <= {rule.get("max_plane_rms", "?")} m, windows of {rule.get("window", "?")} frames,
  label from their median depth); dropped: {dropped or "none"};
- training frames: {report["train_frames"]}; validation: the held-out scene shard(s)
  {", ".join(report["val_shards"])} (scenes never trained on).

## Training

- command: `{report["command"]}`
- seed {cfg["seed"]}, {cfg["steps"]} steps of {cfg["batch"]} frames from `{cfg["init"]}`, Adam
  (lr {cfg["lr"]}, cosine decay, weight decay {cfg["weight_decay"]}), {cfg["threads"]} torch
  thread(s), CPU; {report["train_minutes"]} min on {report.get("machine", "?")}
  ({report["date"]}), after {report.get("prepare_minutes", "?")} min preparing.

## Metrics

Held-out site scenes, against their depth labels (a site has no other truth): mask IoU median
{v["iou_median"]:.4f}, mean {v["iou_mean"]:.4f}, 10th percentile {v["iou_p10"]:.4f} over
{v["frames"]} frames. Against the simulator's truth on held-out objects:
docs/results/site_adaptation.md.

## Limits

Learns what the depth labels say: where the depth segmentation is wrong at the site (objects
thinner than its height threshold, holes in the depth of the object), so is the label.
"""


# --------------------------------------------------------------------------------------------
# Command line: pushbot train segmentation
# --------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot train segmentation``."""
    d = TrainConfig()
    parser.add_argument("--data", type=Path, default=Path("out/perception_data"),
                        help="data set of `pushbot data perception` (at least 2 shards)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=OUT_DIR / DEFAULT_WEIGHTS,
                       help="weights file; the report (.json) and model card (.md) are written "
                            "beside it")
    where.add_argument("--install", action="store_true",
                       help="write the weights, report and card over the bundled ones "
                            "(push_perception/models/segmentation.*), which the node loads")
    parser.add_argument("--init", default="",
                        help="start from these weights instead of a random initialisation: "
                             "`bundled` (fine-tune the bundled network, e.g. on `pushbot data "
                             "record` site frames) or a checkpoint path; not with --install")
    parser.add_argument("--steps", type=int, default=None,
                        help=f"optimiser steps (default {d.steps}; {FINE_TUNE.steps} with "
                             "--init)")
    parser.add_argument("--batch", type=int, default=d.batch, help="frames per step")
    parser.add_argument("--lr", type=float, default=None,
                        help=f"peak learning rate (default {d.lr}; {FINE_TUNE.lr} with --init)")
    parser.add_argument("--val-shards", type=int, default=d.val_shards,
                        help=f"final shards held out for validation (default {d.val_shards}; "
                             "a site data set has one shard per scene)")
    parser.add_argument("--seed", type=int, default=d.seed, help="seed")
    parser.add_argument("--threads", type=int, default=d.threads,
                        help="torch threads (1: the machine is shared)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run ``pushbot train segmentation``; returns the exit code.

    Raises
    ------
    ValueError
        Before training, if the data set has no shards or fewer than ``val_shards + 1``, or
        an option is out of range.
    """
    import sys

    init = getattr(args, "init", "")
    if init and args.install:
        raise ValueError("--init with --install: a fine-tuned network is written to --out and "
                         "loaded through segmentation_node's weights parameter; the bundled "
                         "weights are only replaced by a training from scratch")
    base = FINE_TUNE if init else TrainConfig()
    cfg = TrainConfig(steps=base.steps if args.steps is None else args.steps, batch=args.batch,
                      lr=base.lr if args.lr is None else args.lr, seed=args.seed,
                      threads=args.threads, val_shards=getattr(args, "val_shards", 1),
                      init=init)
    if cfg.val_shards < 1:
        raise ValueError(f"--val-shards {cfg.val_shards}: expected an integer >= 1")
    if init:
        initial_net(init)  # an unreadable --init fails before the data are prepared
    for name in ("steps", "batch", "threads"):
        if getattr(cfg, name) < 1:
            raise ValueError(f"--{name} {getattr(cfg, name)}: expected an integer >= 1")
    if not (math.isfinite(cfg.lr) and cfg.lr > 0):
        raise ValueError(f"--lr {cfg.lr}: expected a positive number")
    _check_shards(args.data, cfg)
    out = installed_weights() if args.install else args.out
    net, report = train(args.data, cfg, progress=not args.no_progress)
    command = "pushbot " + " ".join(sys.argv[1:]) if sys.argv[1:] else "pushbot train segmentation"
    save(net, report, out, command)
    v = report["validation"]
    print(f"trained {report['train_minutes']} min on {report['train_frames']} frames; "
          f"validation IoU median {v['iou_median']:.4f} (mean {v['iou_mean']:.4f}, p10 "
          f"{v['iou_p10']:.4f}) on {v['frames']} frames; weights: {out}")
    return 0
