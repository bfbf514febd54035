"""Training data for the segmentation CNN: rendered RGB-D frames with ground truth.

ROS-free. Uses the sim bridge's pybullet world (:class:`sim_bridge.world.PushWorld`) in this
process; no DDS. ``pushbot data perception --n N --out DIR`` is the command line.

What a sample holds (one rendered frame)
-----------------------------------------
- ``rgb`` (H, W, 3) uint8 colour image; ``depth`` (H, W) uint16 z-depth in units of
  ``DEPTH_UNIT`` = 0.1 mm, 0 = no return (RealSense-style integer depth: lossless for the
  1 mm-quantised noisy depth, 0.05 mm rounding for noise-free depth); ``mask`` (H, W) bool of
  the object's visible pixels (top face and visible side walls). All in
  ``camera_color_optical_frame``.
- ``camera_matrix`` (3, 3) K in pixels, ``T_world_camera`` (4, 4) world <- optical frame (the
  true, possibly jittered pose), ``pose`` (3,) ground-truth ``(x, y, theta)`` of the object
  frame (origin = area centroid) in ``world``; ``pusher`` (3,) position of the pusher axis'
  lowest point in ``world`` (NaN when parked out of view).
- ``thickness``, ``mass`` (kg), ``com`` (2,) in the object frame, ``object`` (name: a library
  name or ``proc_<kind>_<shard>_<k>`` for a generated shape).
- the outline: points and outward unit normals in the object frame, counter-clockwise, about
  2 mm apart (``ObjectSpec.outline``); stored concatenated with offsets (see below).

Scenes
------
Objects: the MIT pushing-dataset objects *except* the held-out test objects
``push_core.objects.TEST_OBJECTS`` (tri1, butter, hex), and procedurally generated shapes
(``random_shape``, i.e. :func:`push_core.procedural.training_shape`): convex polygons,
ellipses, star-shaped (non-convex) polygons, L/T-shaped polygons and smooth blobs (radial
Fourier series, butter-like waists), 5-18 cm across, 5-25 mm thick. Each scene is one
:class:`~sim_bridge.world.WorldConfig` with a fresh seed (random mass/COM/friction, random
colours and lighting for most scenes, camera pose jitter, depth noise in half of them, a
varied viewpoint in some); ``poses_per_scene`` frames are
rendered per scene with the object teleported to random poses. In a fraction of the frames
the pusher stands near the object (touching it up to 3 cm away, sometimes raised), elsewhere
in the workspace, or the object is out of view (empty mask).

The pusher is placed with ``PushWorld.place_pusher`` (a teleport, not a push: frames in which
the pusher touches the object are what the network must learn to separate) and parked again
with ``PushWorld.park_pusher`` before the object is moved, so physics never sees the two
overlap.

Reproducibility and files
-------------------------
Shard ``k`` of a run with seed ``s`` is generated from ``numpy.random.SeedSequence([s, k])``
only, so any shard can be regenerated alone and the data are identical run to run (pybullet's
TinyRenderer is deterministic). Files: ``DIR/shard_00000.npz`` ... (``numpy.savez_compressed``,
``shard_size`` samples each, arrays stacked along axis 0; the outline as ``outline_points``
(M, 2), ``outline_normals`` (M, 2) and ``outline_offsets`` (N + 1,) so that sample ``i`` owns
rows ``offsets[i]:offsets[i + 1]``) and ``DIR/meta.json`` (the :class:`DataConfig`, the
training object names, the file format version).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from push_core.geometry import closest_point_on_polyline, object_to_world
from push_core.objects import TEST_OBJECTS, ObjectSpec, library_names
from push_core.procedural import TRAINING_KINDS, training_shape

__all__ = [
    "DEPTH_UNIT",
    "FORMAT_VERSION",
    "DataConfig",
    "Sample",
    "add_arguments",
    "decode_depth",
    "encode_depth",
    "generate",
    "generate_shard",
    "iter_samples",
    "random_shape",
    "run",
    "training_objects",
]

#: Depth unit of the stored uint16 depth images, metres (0 = no return).
DEPTH_UNIT = 1e-4
#: Version of the shard layout written into meta.json.
FORMAT_VERSION = 1
#: Frames per shard of larger data sets (``--shard-size`` default from 200 frames on).
SHARD_SIZE = 100
#: Smallest data set ``pushbot data perception`` makes: two shards of one frame, one of them
#: held out for validation by ``pushbot train segmentation``.
MIN_FRAMES = 2
#: Where out-of-view objects are put: behind the default camera (which stands near x = 0.5 m).
_OUT_OF_VIEW = (1.4, 0.0)


@dataclass(frozen=True)
class DataConfig:
    """Everything that defines a generated data set (with ``seed``, it is reproducible).

    Attributes
    ----------
    n : int
        Number of samples (frames), >= 1.
    seed : int
        Seed of the whole data set, >= 0.
    shard_size : int
        Samples per ``.npz`` shard.
    width, height : int
        Image size in pixels (the node's default camera is 640 x 480).
    poses_per_scene : int
        Frames rendered per world build (same object, appearance, camera; new pose each).
    library_fraction : float
        Fraction of scenes with a MIT training object; the rest use generated shapes.
    pusher_near, pusher_elsewhere : float
        Fractions of frames with the pusher near the object (0.5 mm to 3 cm from its outline)
        or somewhere else in the workspace; otherwise it is parked out of view.
    empty_fraction : float
        Fraction of frames with the object out of view (empty mask).
    depth_noise_fraction : float
        Fraction of scenes with RealSense-like depth noise.
    plain_appearance_fraction : float
        Fraction of scenes with the world's default (non-randomised) colours and lighting.
    viewpoint_fraction : float
        Fraction of scenes whose camera elevation, distance and azimuth are varied (45-70 deg,
        0.7-0.9 m, +-15 deg) on top of the pose jitter every scene has.
    """

    n: int
    seed: int = 0
    shard_size: int = SHARD_SIZE
    width: int = 640
    height: int = 480
    poses_per_scene: int = 4
    library_fraction: float = 0.35
    pusher_near: float = 0.4
    pusher_elsewhere: float = 0.1
    empty_fraction: float = 0.02
    depth_noise_fraction: float = 0.5
    plain_appearance_fraction: float = 0.15
    viewpoint_fraction: float = 0.2

    def __post_init__(self) -> None:
        for name, low in (("n", 1), ("seed", 0), ("shard_size", 1), ("width", 8),
                          ("height", 8), ("poses_per_scene", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < low:
                raise ValueError(f"{name}: expected an integer >= {low}, got {value!r}")
            object.__setattr__(self, name, int(value))
        for name in ("library_fraction", "pusher_near", "pusher_elsewhere", "empty_fraction",
                     "depth_noise_fraction", "plain_appearance_fraction", "viewpoint_fraction"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0.0 <= value <= 1.0):
                raise ValueError(f"{name}: expected a fraction in [0, 1], got {value!r}")
        if self.pusher_near + self.pusher_elsewhere > 1.0:
            raise ValueError("pusher_near + pusher_elsewhere must not exceed 1")

    @property
    def n_shards(self) -> int:
        """Number of shards, ``ceil(n / shard_size)``."""
        return math.ceil(self.n / self.shard_size)

    def shard_length(self, index: int) -> int:
        """Number of samples in shard ``index`` (the last one may be short)."""
        if not 0 <= index < self.n_shards:
            raise ValueError(f"shard index {index} outside [0, {self.n_shards})")
        return min(self.shard_size, self.n - index * self.shard_size)


@dataclass(frozen=True)
class Sample:
    """One frame of a data set, decoded (see the module docstring for frames and units)."""

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    mask: NDArray[np.bool_]
    camera_matrix: NDArray[np.float64]
    T_world_camera: NDArray[np.float64]  # noqa: N815 - the world's name
    pose: NDArray[np.float64]
    pusher: NDArray[np.float64]
    thickness: float
    object: str
    outline_points: NDArray[np.float64]
    outline_normals: NDArray[np.float64]


def training_objects() -> tuple[str, ...]:
    """Library objects used for training: all but ``TEST_OBJECTS`` (tri1, butter, hex)."""
    return tuple(n for n in library_names() if n not in TEST_OBJECTS)


# --------------------------------------------------------------------------------------------
# Depth encoding
# --------------------------------------------------------------------------------------------
def encode_depth(depth: NDArray[np.floating]) -> NDArray[np.uint16]:
    """Metric z-depth (H, W) float (NaN = no return) -> uint16 in ``DEPTH_UNIT`` (0 = none).

    Raises
    ------
    ValueError
        If a finite depth is not in ``(0, 65535 * DEPTH_UNIT]`` (0 < z <= 6.55 m).
    """
    d = np.asarray(depth, dtype=np.float64)
    valid = np.isfinite(d)
    units = np.zeros(d.shape, dtype=np.float64)
    units[valid] = np.round(d[valid] / DEPTH_UNIT)
    if np.any(units[valid] < 1) or np.any(units[valid] > 65535):
        raise ValueError(f"depth must be in (0, {65535 * DEPTH_UNIT:.4f}] m where finite")
    return units.astype(np.uint16)


def decode_depth(encoded: NDArray[np.uint16]) -> NDArray[np.float32]:
    """Inverse of :func:`encode_depth`: float32 metres with NaN where the value is 0."""
    e = np.asarray(encoded)
    depth = e.astype(np.float32) * np.float32(DEPTH_UNIT)
    depth[e == 0] = np.nan
    return depth


# --------------------------------------------------------------------------------------------
# Procedural shapes
# --------------------------------------------------------------------------------------------
SHAPE_KINDS = TRAINING_KINDS


def random_shape(rng: np.random.Generator, kind: str | None = None) -> dict[str, Any]:
    """A random object specification (the dict of an object specification file).

    This is :func:`push_core.procedural.training_shape` (families ``kind`` in
    :data:`SHAPE_KINDS`, drawn uniformly when None; sizes; validation), which holds the shape
    code and keeps the draws with which the training data were generated.
    """
    return training_shape(rng, kind)


# --------------------------------------------------------------------------------------------
# Generation
# --------------------------------------------------------------------------------------------
def generate_shard(cfg: DataConfig, index: int, workdir: Path) -> dict[str, NDArray[Any]]:
    """Render shard ``index`` of the data set ``cfg`` (deterministic in ``(cfg, index)``).

    Parameters
    ----------
    cfg : DataConfig
    index : int
        Shard number in ``[0, cfg.n_shards)``.
    workdir : pathlib.Path
        Directory for the temporary object specification files of generated shapes.

    Returns
    -------
    dict of str to ndarray
        The shard's arrays (the layout of the module docstring), ready for ``np.savez``.
    """
    from sim_bridge.world import PushWorld

    n = cfg.shard_length(index)
    rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, index]))
    records: list[dict[str, Any]] = []
    world: PushWorld | None = None
    scene = 0
    try:
        while len(records) < n:
            wcfg, spec_name = _scene_config(cfg, rng, index, scene, workdir)
            if world is None:
                world = PushWorld(wcfg)
            else:
                world.reset(wcfg)
            spec = world.object_spec
            points, normals = spec.outline(0.002)
            for _ in range(min(cfg.poses_per_scene, n - len(records))):
                records.append(_render_sample(world, cfg, rng, spec, spec_name, points, normals))
            scene += 1
    finally:
        if world is not None:
            world.close()
    return _stack(records)


def _scene_config(cfg: DataConfig, rng: np.random.Generator, shard: int, scene: int,
                  workdir: Path) -> tuple[Any, str]:
    from sim_bridge.world import CameraConfig, WorldConfig

    if rng.random() < cfg.library_fraction:
        names = training_objects()
        obj: str = names[int(rng.integers(len(names)))]
        name = obj
    else:
        spec = random_shape(rng)
        kind = "ellipse" if spec["shape"]["type"] == "ellipse" else "polygon"
        name = f"proc_{kind}_{shard:05d}_{scene:04d}"
        path = workdir / f"{name}.json"
        path.write_text(json.dumps({"name": name, **spec}))
        obj = str(path)
    camera = CameraConfig(width=cfg.width, height=cfg.height)
    vary = rng.random() < cfg.viewpoint_fraction
    elevation, distance, azimuth = (rng.uniform(45.0, 70.0), rng.uniform(0.7, 0.9),
                                    rng.uniform(-15.0, 15.0))
    if vary:
        camera = dataclasses.replace(camera, elevation_deg=float(elevation),
                                     distance=float(distance), azimuth_deg=float(azimuth))
    wcfg = WorldConfig(
        object=obj, randomize=True, seed=int(rng.integers(2**31 - 1)), camera=camera,
        depth_noise=bool(rng.random() < cfg.depth_noise_fraction),
        randomize_appearance=bool(rng.random() >= cfg.plain_appearance_fraction),
        randomize_camera=True,
    )
    return wcfg, name


def _render_sample(world: Any, cfg: DataConfig, rng: np.random.Generator, spec: ObjectSpec,
                   name: str, points: NDArray[np.float64],
                   normals: NDArray[np.float64]) -> dict[str, Any]:
    from sim_bridge.world import PUSHER_GAP

    (x0, x1), (y0, y1) = world.workspace
    pose = np.array([rng.uniform(x0 + 0.03, x1 - 0.03), rng.uniform(y0 + 0.03, y1 - 0.03),
                     rng.uniform(-np.pi, np.pi)])
    u_empty, u_pusher = rng.random(), rng.random()
    if u_empty < cfg.empty_fraction:
        pose[:2] = _OUT_OF_VIEW
    world.set_object_pose(pose)
    pose = world.object_pose()  # settled (the friction anchor keeps it within ~0.03 mm)
    pusher = np.full(3, np.nan)
    radius = world.config.pusher_radius
    if u_pusher < cfg.pusher_near:
        k = int(rng.integers(len(points)))
        gap = radius + rng.uniform(5e-4, 0.03)
        xy = object_to_world(pose, points[k] + gap * normals[k])
    elif u_pusher < cfg.pusher_near + cfg.pusher_elsewhere:
        xy = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
    else:
        xy = None
    if xy is not None:
        _, _, dist, _ = closest_point_on_polyline(world.object_outline(), xy)
        if dist > radius + 3e-4:  # never inside or overlapping the object
            lift = rng.uniform(0.0, 0.05) if rng.random() < 0.2 else 0.0
            pusher = np.array([xy[0], xy[1], PUSHER_GAP + lift])
            world.place_pusher(xy, lift)
    frame = world.render()
    if np.all(np.isfinite(pusher)):
        world.park_pusher()
    return {
        "rgb": frame.rgb, "depth": encode_depth(frame.depth), "mask": frame.mask,
        "camera_matrix": frame.camera_matrix, "T_world_camera": frame.T_world_camera,
        "pose": frame.object_pose, "pusher": pusher, "thickness": spec.thickness,
        "mass": spec.mass, "com": np.asarray(spec.com), "object": name,
        "outline_points": points, "outline_normals": normals,
    }


def _stack(records: list[dict[str, Any]]) -> dict[str, NDArray[Any]]:
    out: dict[str, NDArray[Any]] = {}
    for key in ("rgb", "depth", "mask", "camera_matrix", "T_world_camera", "pose", "pusher",
                "thickness", "mass", "com"):
        out[key] = np.stack([np.asarray(r[key]) for r in records])
    out["object"] = np.array([r["object"] for r in records])
    lengths = [len(r["outline_points"]) for r in records]
    out["outline_offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    out["outline_points"] = np.concatenate([r["outline_points"] for r in records])
    out["outline_normals"] = np.concatenate([r["outline_normals"] for r in records])
    return out


def shard_path(out: Path, index: int) -> Path:
    """File name of shard ``index`` under ``out``."""
    return Path(out) / f"shard_{index:05d}.npz"


def generate(cfg: DataConfig, out: Path, progress: bool = True, overwrite: bool = False) -> None:
    """Generate the whole data set ``cfg`` into directory ``out``.

    Existing shards of the same configuration are kept (an interrupted run resumes), unless
    ``overwrite``; a directory holding a different configuration is refused.

    Raises
    ------
    ValueError
        If ``out`` holds a data set generated with a different configuration.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {"format_version": FORMAT_VERSION, "config": dataclasses.asdict(cfg),
            "training_objects": list(training_objects()),
            "held_out": list(TEST_OBJECTS)}
    meta_path = out / "meta.json"
    if meta_path.exists() and not overwrite:
        old = json.loads(meta_path.read_text())
        if old.get("config") != meta["config"] or old.get("format_version") != FORMAT_VERSION:
            raise ValueError(f"{out} holds a data set with another configuration "
                             f"({old.get('config')}); use another directory or --overwrite")
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    todo = [i for i in range(cfg.n_shards) if overwrite or not shard_path(out, i).exists()]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=cfg.n, unit="frame", desc="perception data",
                   initial=cfg.n - sum(cfg.shard_length(i) for i in todo))
    with tempfile.TemporaryDirectory(prefix="pushbot_shapes_") as tmp:
        for i in todo:
            arrays = generate_shard(cfg, i, Path(tmp))
            partial = shard_path(out, i).with_suffix(".tmp.npz")
            np.savez_compressed(partial, **arrays)
            partial.replace(shard_path(out, i))
            if bar is not None:
                bar.update(cfg.shard_length(i))
    if bar is not None:
        bar.close()


def iter_samples(directory: Path) -> Iterator[Sample]:
    """Decode every sample of a generated data set, shard by shard, in order."""
    directory = Path(directory)
    shards = sorted(directory.glob("shard_*.npz"))
    shards = [s for s in shards if not s.name.endswith(".tmp.npz")]
    if not shards:
        raise ValueError(f"{directory}: no shard_*.npz files (run pushbot data perception)")
    for path in shards:
        with np.load(path) as z:
            arrays = {k: z[k] for k in z.files}
        off = arrays["outline_offsets"]
        for i in range(len(arrays["rgb"])):
            yield Sample(
                rgb=arrays["rgb"][i], depth=decode_depth(arrays["depth"][i]),
                mask=arrays["mask"][i], camera_matrix=arrays["camera_matrix"][i],
                T_world_camera=arrays["T_world_camera"][i], pose=arrays["pose"][i],
                pusher=arrays["pusher"][i], thickness=float(arrays["thickness"][i]),
                object=str(arrays["object"][i]),
                outline_points=arrays["outline_points"][off[i]:off[i + 1]],
                outline_normals=arrays["outline_normals"][off[i]:off[i + 1]],
            )


# --------------------------------------------------------------------------------------------
# Command line: pushbot data perception
# --------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``pushbot data perception``."""
    parser.add_argument("--n", type=int, required=True,
                        help=f"number of frames to render, >= {MIN_FRAMES} (about 0.6 MB per "
                             "640 x 480 frame)")
    parser.add_argument("--out", type=Path, required=True,
                        help="output directory (e.g. out/perception_data; keep it out of git)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the data set")
    parser.add_argument("--shard-size", type=int, default=None,
                        help=f"frames per .npz shard (default: {SHARD_SIZE}, or half of --n "
                             f"rounded up below {2 * SHARD_SIZE} frames, so that training has "
                             "a shard to hold out)")
    parser.add_argument("--width", type=int, default=640, help="image width, px")
    parser.add_argument("--height", type=int, default=480, help="image height, px")
    parser.add_argument("--overwrite", action="store_true",
                        help="regenerate existing shards instead of resuming")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def default_shard_size(n: int) -> int:
    """Frames per shard when ``--shard-size`` is not given: :data:`SHARD_SIZE`, or
    ``ceil(n / 2)`` for smaller sets, so that every set of at least :data:`MIN_FRAMES` frames
    has the two shards ``pushbot train segmentation`` needs (the last is held out)."""
    return max(1, min(SHARD_SIZE, math.ceil(n / 2)))


def run(args: argparse.Namespace) -> int:
    """Run ``pushbot data perception``; returns the exit code.

    Raises
    ------
    ValueError
        If ``--n`` is below :data:`MIN_FRAMES`, the configuration is invalid, or ``--out``
        holds a data set of another configuration (checked before anything is rendered).
    """
    if args.n < MIN_FRAMES:
        raise ValueError(f"--n {args.n}: need at least {MIN_FRAMES} frames (training holds "
                         "the last shard out for validation)")
    shard_size = default_shard_size(args.n) if args.shard_size is None else args.shard_size
    cfg = DataConfig(n=args.n, seed=args.seed, shard_size=shard_size, width=args.width,
                     height=args.height)
    if cfg.n_shards < 2:
        print(f"note: {cfg.n} frames in 1 shard of {cfg.shard_size}: `pushbot train "
              "segmentation` needs at least 2 shards (use a smaller --shard-size)",
              file=sys.stderr)
    generate(cfg, args.out, progress=not args.no_progress, overwrite=args.overwrite)
    print(f"wrote {cfg.n} frames in {cfg.n_shards} shard(s) of up to {cfg.shard_size} to "
          f"{args.out}")
    return 0
