"""``pushbot calibrate``: the camera's pose in ``world`` from the arm showing it a board.

Against the running graph (``pushbot up`` with the ChArUco board on the tool; in simulation
``-p calibration.board:=true``): the procedure of :mod:`pushbot.runner.calibration` moves the
arm through ``push_executor_node`` (``executor/joint_goal``, answered on
``executor/goal_result``: planned and checked like a park; a disabled executor plans the
first pose, publishes its path and moves nothing, and the calibration is refused), detects the
board in a ``camera/color/image_raw`` frame taken after each move, and solves. The executor's
model and limits are its own (``/robot_description``, its parameters); the camera's
intrinsics are ``camera/color/camera_info``. It never reads ``camera/color/extrinsics``.

On success it writes the extrinsics (``--out``, a parameter YAML of ``camera_extrinsics``:
``frame_id``, ``child_frame_id``, ``translation``, ``rotation`` (x, y, z, w), the residuals
and the 1-sigma uncertainty), prints a ready ``ros2 run tf2_ros static_transform_publisher``
line for a full install, and ``pushbot calibrate --serve`` publishes the saved extrinsics as
the latched ``camera/color/extrinsics`` until Ctrl-C (the pip install's source: tf2 has no
PyPI wheel). A refusal is one line (``pushbot calibrate: refused (<kind>): <reason>``, exit
status 3) and the previous file is kept. The arm goes back to its park posture at the end.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["add_arguments", "read_extrinsics", "run_calibrate", "static_transform_line",
           "write_extrinsics"]

#: Exit status of a refused calibration (the previous one kept).
EXIT_REFUSED = 3
DEFAULT_OUT = Path("~/.config/pushbot/camera_extrinsics.yaml")
#: The node whose parameters the executor's model and limits are read from.
EXECUTOR = "/push_executor_node"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--poses", type=int, default=15,
                        help="generated views after the first (at most 20 poses in all)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the generated poses")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT,
                        help="the extrinsics YAML (written only on success)")
    parser.add_argument("--camera-guess", type=float, nargs=7, default=None,
                        metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                        help="rough pose of the camera's optical frame in world, enough to see "
                        "the board (default: --out's, else the simulator's default viewpoint)")
    parser.add_argument("--mount", type=float, nargs=7, default=None,
                        metavar=("X", "Y", "Z", "QX", "QY", "QZ", "QW"),
                        help="the board's frame on the flange as designed (default: the "
                        "simulator's board)")
    parser.add_argument("--move-timeout", type=float, default=60.0,
                        help="longest wait for one move, s")
    parser.add_argument("--no-park", action="store_true", help="leave the arm at the last pose")
    parser.add_argument("--serve", action="store_true",
                        help="publish --out as the latched camera/color/extrinsics until Ctrl-C")


def _pose_matrix(values: Any) -> NDArray[np.float64]:
    from scipy.spatial.transform import Rotation

    v = np.asarray(values, dtype=float).ravel()
    if v.shape != (7,) or not np.all(np.isfinite(v)) or abs(np.linalg.norm(v[3:]) - 1) > 1e-3:
        raise ValueError("a pose is x y z qx qy qz qw (finite, a unit quaternion)")
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = Rotation.from_quat(v[3:]).as_matrix(), v[:3]
    return t


def _pose_values(t: NDArray[np.float64]) -> list[float]:
    from push_core.geometry import quaternion_from_matrix

    return [float(x) for x in (*t[:3, 3], *quaternion_from_matrix(t[:3, :3]))]


def write_extrinsics(path: Path, result: Any, poses: int, frame_id: str = "world",
                     child_frame_id: str = "camera_color_optical_frame") -> None:
    """Write the extrinsics YAML (module docstring) atomically (a temporary file renamed)."""
    import yaml

    pose = _pose_values(result.world_camera)
    values = {"frame_id": frame_id, "child_frame_id": child_frame_id,
              "translation": pose[:3], "rotation": pose[3:],
              "tool_board": _pose_values(result.tool_board),
              "rms_px": float(result.rms_px),
              "position_sigma_mm": float(result.position_sigma_mm),
              "rotation_sigma_deg": float(result.rotation_sigma_deg),
              "views_used": int(np.sum(result.used)), "poses": int(poses),
              "date": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("# pushbot calibrate: T_world_camera (docs/CLI.md)\n"
                   + yaml.safe_dump({"camera_extrinsics": {"ros__parameters": values}},
                                    sort_keys=False))
    tmp.replace(path)


def read_extrinsics(path: Path) -> tuple[NDArray[np.float64], str, str]:
    """``T_world_camera`` (4, 4), ``frame_id`` and ``child_frame_id`` of an extrinsics YAML;
    ``ValueError`` naming the file."""
    import yaml

    try:
        v = yaml.safe_load(path.read_text())["camera_extrinsics"]["ros__parameters"]
        return (_pose_matrix([*v["translation"], *v["rotation"]]), str(v["frame_id"]),
                str(v["child_frame_id"]))
    except (KeyError, TypeError, ValueError, yaml.YAMLError) as exc:
        raise ValueError(f"{path}: not an extrinsics file of pushbot calibrate ({exc})"
                         ) from None


def static_transform_line(t: NDArray[np.float64], frame_id: str, child_frame_id: str) -> str:
    """The ``ros2 run tf2_ros static_transform_publisher`` command publishing ``t``."""
    x, y, z, qx, qy, qz, qw = _pose_values(t)
    return ("ros2 run tf2_ros static_transform_publisher "
            f"--x {x:.6f} --y {y:.6f} --z {z:.6f} --qx {qx:.6f} --qy {qy:.6f} "
            f"--qz {qz:.6f} --qw {qw:.6f} --frame-id {frame_id} --child-frame-id "
            f"{child_frame_id}")


def run_calibrate(args: argparse.Namespace) -> int:
    from pushbot.ros2cli.discovery import cli_node, sigterm_as_keyboard_interrupt

    args.out = args.out.expanduser()
    if args.serve:
        t, frame_id, child = read_extrinsics(args.out)
        with sigterm_as_keyboard_interrupt(), cli_node("calibrate") as (node, executor):
            return _serve(node, executor, t, frame_id, child, args.out)
    if not 1 <= args.poses <= 19:
        raise ValueError(f"--poses: 1 to 19, got {args.poses}")
    from push_core.calibration import CalibrationRefused
    from pushbot.runner.calibrate_graph import GraphRobot

    with sigterm_as_keyboard_interrupt(), cli_node("calibrate") as (node, executor):
        robot = GraphRobot(node, executor, EXECUTOR, args.move_timeout)
        try:
            outcome = robot.calibrate(_setup(args, robot), print)
        except CalibrationRefused as refusal:
            kept = (f"the previous calibration ({args.out}) is kept" if args.out.exists()
                    else f"nothing written to {args.out}")
            print(f"pushbot calibrate: refused ({refusal.kind}): {refusal}; {kept}",
                  file=sys.stderr)
            return EXIT_REFUSED
        finally:
            if not args.no_park:
                robot.park()
    r = outcome.result
    write_extrinsics(args.out, r, outcome.moved, robot.world_frame, robot.camera_frame)
    print(f"calibrated from {int(r.used.sum())} of {len(outcome.views)} views "
          f"({outcome.moved} poses, {len(outcome.dropped)} dropped, robot time "
          f"{robot.robot_time:.1f} s): RMS {r.rms_px:.3f} px, 1-sigma "
          f"{r.position_sigma_mm:.3f} mm / {r.rotation_sigma_deg:.4f} deg")
    print(f"wrote {args.out}")
    print("full install: " + static_transform_line(r.world_camera, robot.world_frame,
                                                   robot.camera_frame))
    print(f"pip install: pushbot calibrate --serve --out {args.out}")
    return 0


def _setup(args: argparse.Namespace, robot: Any) -> Any:
    from pushbot.runner.calibration import CalibrationSetup

    if args.camera_guess is not None:
        guess = _pose_matrix(args.camera_guess)
    elif args.out.is_file():
        guess = read_extrinsics(args.out)[0]
    else:
        from sim_bridge.camera import CameraConfig, look_at_pose

        guess = look_at_pose(CameraConfig())
    if args.mount is not None:
        mount = _pose_matrix(args.mount)
    else:
        from push_core.calibration import BoardSpec
        from sim_bridge.calibration_board import board_mount

        mount = board_mount(BoardSpec())
    k, d, size = robot.intrinsics()
    return CalibrationSetup(mount=mount, camera=guess, k=k, size=size, d=d, poses=args.poses,
                            seed=args.seed)


def _serve(node: Any, executor: Any, t: NDArray[np.float64], frame_id: str, child: str,
           path: Path) -> int:
    from geometry_msgs.msg import TransformStamped

    from push_ros.extrinsics import EXTRINSICS_TOPIC
    from push_ros.poses import transform_msg
    from push_ros.qos import LATCHED_QOS

    pub = node.create_publisher(TransformStamped, EXTRINSICS_TOPIC, LATCHED_QOS)
    pub.publish(transform_msg(t, node.get_clock().now().to_msg(), frame_id, child))
    print(f"publishing {path} on {EXTRINSICS_TOPIC} (latched) until Ctrl-C", flush=True)
    try:
        while True:
            executor.spin_once(timeout_sec=1.0)
    except KeyboardInterrupt:
        return 0
