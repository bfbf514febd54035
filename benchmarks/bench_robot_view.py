"""The robot model's view of the arm: time per 640 x 480 frame and agreement with the simulator.

For random postures with the simulated Panda's tool over the workspace (seeded: tips uniform in
the 0.5 m square at heights 2-20 cm, pybullet's IK), :meth:`push_core.robot_view.RobotGeometry
.render` renders the URDF's collision geometry posed by the joints; the simulator's
segmentation buffer of the arm (its visual geometry) is the truth. Reported: render time per
frame (median, p90; repeated renders of each posture), the IoU of the masks (median, min) at
dilations 0 and 2 px, and the depth difference on pixels both call robot. Postures whose arm
covers fewer than 2000 pixels (only the rod's tip in view) are counted but not in the IoU
figures: there a one-pixel outline difference dominates. Writes the ``bench_robot_view``
section of ``docs/RESULTS.md``.

Usage::

    .venv/bin/python benchmarks/bench_robot_view.py [--postures N] [--repeats R] [--no-write]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import format_section, update_section  # noqa: E402

from push_core.robot_view import RobotGeometry  # noqa: E402
from sim_bridge.world import PushWorld, WorldConfig, quiet_stdout  # noqa: E402

#: Fewest true arm pixels of a posture that enters the IoU figures.
MIN_ARM_PIXELS = 2000


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--postures", type=int, default=40)
    parser.add_argument("--repeats", type=int, default=5, help="timed renders per posture")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-write", action="store_true")
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    with quiet_stdout():
        world = PushWorld(WorldConfig(robot="arm", object="butter", object_pose=(0.2, 0.25, 0)))
    t0 = time.perf_counter()
    robot = RobotGeometry.from_urdf(world.robot_description,
                                    base_pose=world.config.arm_base_pose)
    load_s = time.perf_counter() - t0
    arm, (w, h) = world.arm, world.image_size
    k, t = world.camera_matrix, world.T_world_camera
    times, iou = [], {0: [], 2: []}
    depth_err, small = [], 0
    for _ in range(args.postures):
        tip = (rng.uniform(-0.25, 0.25), rng.uniform(-0.25, 0.25), rng.uniform(0.02, 0.2))
        arm.set_positions(arm.inverse_kinematics(tip))
        state = arm.state()
        names, q = list(state.names), state.positions
        true = world.arm_mask()
        frame = world.render()
        for _ in range(args.repeats):
            start = time.perf_counter()
            mask, depth = robot.render(k, t, w, h, names, q)
            times.append(time.perf_counter() - start)
        if true.sum() < MIN_ARM_PIXELS:
            small += 1
            continue
        for dilate in iou:
            m = robot.render(k, t, w, h, names, q, dilate_px=dilate).mask
            iou[dilate].append(np.count_nonzero(m & true) / np.count_nonzero(m | true))
        both = mask & true & np.isfinite(frame.depth)
        depth_err.append(float(np.median(np.abs(depth[both] - frame.depth[both]))))
    ms = 1e3 * np.array(times)
    rows = [f"| {d} | {np.median(v):.3f} | {np.min(v):.3f} |" for d, v in iou.items()]
    body = "\n".join([
        f"Simulated Panda (URDF collision geometry: {robot.triangle_count} triangles), "
        f"{args.postures} random postures with the tool tip over the workspace at 2-20 cm "
        f"(seed {args.seed}), 640 x 480, the default camera; truth = the simulator's "
        "segmentation buffer of the arm (its visual meshes). Model load "
        f"{1e3 * load_s:.0f} ms (once per robot description).", "",
        f"- render time per frame: median {np.median(ms):.1f} ms, p90 "
        f"{np.percentile(ms, 90):.1f} ms ({len(ms)} renders, forward kinematics + "
        "rasterisation, no dilation)",
        f"- depth on pixels both call robot: median of the per-posture median |difference| "
        f"{1e3 * np.median(depth_err):.2f} mm",
        f"- postures with fewer than {MIN_ARM_PIXELS} true arm pixels (only the rod's tip in "
        f"view; left out of the IoU): {small} of {args.postures}", "",
        "| dilate px | IoU median | IoU min |", "|---|---|---|", *rows])
    section = format_section("Robot mask from the URDF (`bench_robot_view`)",
                             "python benchmarks/bench_robot_view.py", body)
    print(section)
    if not args.no_write:
        update_section("bench_robot_view", section)
    world.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
