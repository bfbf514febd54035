"""Reachability of the planner's workspace by the simulator's arm (Panda + 0.20 m rod).

For a grid over the planner's workspace x, y in [-0.25, 0.25] m (2.5 cm spacing) and the ring
of approach points up to 6 cm outside it, solve the inverse kinematics of the tool tip at
0.01 m above the table with the rod vertical (damped least squares on pybullet's Jacobian, 4
start postures, joint limits enforced; a point counts as reached when tip error and rod axis
error are both below 1e-5) for each candidate arm base pose, and report the fraction reached
and the radial band (distance from the base axis) that is reachable. Measurement code only:
the robot side (push_executor) plans with its own kinematics.

Writes ``docs/results/bench_arm_reach.md``, rendered from the figures saved beside it
(``bench_arm_reach.json``; ``--render`` writes the page again from them without measuring).

Usage::

    .venv/bin/python benchmarks/bench_arm_reach.py [--no-write]
    .venv/bin/python benchmarks/bench_arm_reach.py --render
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
import pybullet as p
from pybullet_utils.bullet_client import BulletClient

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _results  # noqa: E402

from sim_bridge.arm_robot import DEFAULT_BASE_POSE, DEFAULT_PARK, ArmRobot, arm_urdf  # noqa: E402

TIP_HEIGHT = 0.01
SECTION = "bench_arm_reach"
TITLE = "Arm reachability (simulator arm mode)"
RENDER = "python benchmarks/bench_arm_reach.py --render"
CANDIDATES = ((-0.55, 0.0, 0.0, 0.0), (-0.52, 0.0, 0.0, 0.0), DEFAULT_BASE_POSE)
SEEDS = (DEFAULT_PARK, (0, 0.3, 0, -2.0, 0, 2.3, 0.785), (0, 0.8, 0, -1.0, 0, 1.8, 0.785),
         (0, -0.3, 0, -2.6, 0, 2.3, 0.785))


def solve(c: BulletClient, arm: ArmRobot, target: np.ndarray, q: np.ndarray) -> bool:
    """Damped least squares for tip position + vertical rod; True when converged."""
    down = np.array([0.0, 0.0, -1.0])
    lo, hi = arm.limits[:, 0] + 1e-4, arm.limits[:, 1] - 1e-4
    for _ in range(200):
        for j, qj in zip(arm.joints, q, strict=True):
            c.resetJointState(arm.body, j, float(qj), 0.0)
        tip, ax = arm.tip_position(), arm.rod_axis()
        err = np.r_[target - tip, down - ax]
        if np.linalg.norm(err[:3]) < 1e-5 and np.linalg.norm(err[3:]) < 1e-5:
            return True
        jl, ja = c.calculateJacobian(arm.body, arm.tip, [0, 0, 0], list(map(float, q)),
                                     [0.0] * 7, [0.0] * 7)
        skew = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
        jac = np.vstack([np.array(jl), -skew @ np.array(ja)])
        q = np.clip(q + jac.T @ np.linalg.solve(jac @ jac.T + 1e-3 * np.eye(6), err), lo, hi)
    return False


def reached(c: BulletClient, arm: ArmRobot, base: tuple, x: float, y: float) -> bool:
    phi = np.arctan2(y - base[1], x - base[0]) - base[3]
    for seed in SEEDS:
        q = np.array(seed, dtype=float)
        q[0] = phi
        if solve(c, arm, np.array([x, y, TIP_HEIGHT]), q):
            return True
    return False


def render(figures: dict) -> str:
    """The page's text from the saved figures (:func:`measure`)."""
    lines = ["| base pose (x, y, z, yaw) in world | workspace reached | approach ring "
             "reached | reachable distance from the base axis |", "|---|---|---|---|"]
    lines += [f"| {tuple(b)} | {100 * w:.1f} % | {100 * r:.1f} % | {lo:.2f} - {hi:.2f} m |"
              for b, w, r, lo, hi in figures["rows"]]
    return "\n".join(lines) + (
        f"\n\nTool tip {figures['tip_height']} m above the table, rod (0.20 m) vertical; "
        f"workspace grid {figures['core_points']} points (2.5 cm) over [-0.25, 0.25]^2 m, "
        f"approach ring {figures['ring_points']} points up to 6 cm outside it. The default "
        f"`arm.base_pose` is {tuple(figures['default_base_pose'])} (a 0.15 m pedestal): on the "
        "bare table (z = 0) the band is too narrow for the 0.5 m square.")


def measure() -> dict:
    """Reachability per candidate base; the figures :func:`render` writes the page from."""
    c = BulletClient(connection_mode=p.DIRECT)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(arm_urdf(0.0048))
    table = c.createMultiBody(0.0, c.createCollisionShape(p.GEOM_PLANE))
    core = np.arange(-0.25, 0.2501, 0.025)
    ring_axis = np.arange(-0.31, 0.3101, 0.031)
    core_pts = [(x, y) for x in core for y in core]
    ring_pts = [(x, y) for x in ring_axis for y in ring_axis if max(abs(x), abs(y)) > 0.25]
    rows = []
    for base in CANDIDATES:
        c.resetSimulation()
        table = c.createMultiBody(0.0, c.createCollisionShape(p.GEOM_PLANE))
        arm = ArmRobot(c, f.name, base, DEFAULT_PARK, 0.3, table, table)
        r_core = [reached(c, arm, base, x, y) for x, y in core_pts]
        r_ring = [reached(c, arm, base, x, y) for x, y in ring_pts]
        radii = np.arange(0.08, 0.95, 0.01)
        band = [r for r in radii if reached(c, arm, base, base[0] + r, base[1])]
        rows.append((base, float(np.mean(r_core)), float(np.mean(r_ring)), float(min(band)),
                     float(max(band))))
        print(f"base {base}: workspace {100 * np.mean(r_core):.1f} % of {len(core_pts)}, "
              f"approach ring {100 * np.mean(r_ring):.1f} % of {len(ring_pts)}, radial band "
              f"[{min(band):.2f}, {max(band):.2f}] m", flush=True)
    Path(f.name).unlink()
    return {"rows": rows, "core_points": len(core_pts), "ring_points": len(ring_pts),
            "tip_height": TIP_HEIGHT, "default_base_pose": DEFAULT_BASE_POSE}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    _results.add_page_options(parser)
    args = parser.parse_args(argv)
    if args.render:
        print(_results.publish(SECTION, TITLE, render, RENDER))
        return 0
    figures = measure()
    if not args.no_write:
        print(_results.publish(SECTION, TITLE, render, RENDER, figures=figures,
                               command=".venv/bin/python benchmarks/bench_arm_reach.py"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
