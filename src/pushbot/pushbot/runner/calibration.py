"""The calibration procedure of ``pushbot calibrate``: poses, moves, detection, the solve.

ROS-free: the robot is a :class:`CalibrationRobot` (the command's is the running graph's
executor, the evaluation's the simulator in process). The procedure:

1. **A first view.** Tool poses made for the camera's guessed pose (the previous calibration,
   or the nominal viewpoint) and the board's designed mounting, untilted, tried in turn until
   one shows the board; the camera's guess is then that view's (the tool pose by forward
   kinematics of the measured joints, the mounting as designed, the board's PnP pose).
2. **The views.** :func:`push_core.calibration.board_facing_poses` for that guess (rotation
   spread about three axes), each turned into a posture by the 6-D inverse kinematics
   (:func:`push_executor.joint_goal.pose_ik`) and checked like the executor checks a joint goal
   (:func:`push_executor.joint_goal.plan_joint_goal` from the previous posture); a pose
   without a converged posture or whose motion fails a check is dropped and the next one
   taken. Each reachable posture is sent; after it is reached the board is detected in a
   colour frame taken since, and the view's tool pose is the forward kinematics of the
   *measured* joints.
3. **The solve** (:func:`push_core.calibration.solve_eye_to_hand`), at most
   :data:`MAX_POSES` poses moved to in all.

Refusals are :class:`push_core.calibration.CalibrationRefused` (one line, ``kind``): the
solver's (``board``, ``degenerate``, ``residual``), ``robot`` (the executor refused a move for
a reason no other pose avoids: disabled, no joint state, no controller, ...) and ``reach``
(fewer reachable poses than the solver needs). The caller keeps the previous calibration.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from push_core.calibration import (
    BoardSpec,
    CalibrationRefused,
    HandEyeResult,
    SolveConfig,
    View,
    board_facing_poses,
    camera_guess,
    detect_board,
    solve_eye_to_hand,
)
from push_executor.joint_goal import plan_joint_goal, pose_ik
from push_executor.kinematics import ArmKinematics
from push_executor.motion_types import MotionConfig, PushRefused

__all__ = ["MAX_POSES", "ROBOT_KINDS", "CalibrationOutcome", "CalibrationRobot",
           "CalibrationSetup", "pnp_pose", "run_calibration"]

#: Most poses moved to in one calibration (the first view's tries included).
MAX_POSES = 20
#: Untilted first-view poses moved to (of four times as many made) before giving up on seeing
#: the board.
FIRST_TRIES = 3
#: Refusal kinds of a move that no other pose avoids: the calibration stops.
ROBOT_KINDS = ("disabled", "no_state", "no_controller", "no_model", "state", "timeout",
               "cancelled", "fault")
#: Inverse kinematics tolerance (m, rad) for a generated pose to count as reachable.
IK_TOLERANCE = 1e-6
#: Random start postures (seeded, within the limits) the inverse kinematics tries after the
#: measured and the reference posture, and its iterations per start: from those two alone, a
#: pose facing a camera moved a few centimetres often stalls at a joint limit.
IK_RESTARTS, IK_ITERATIONS = 8, 1000


class CalibrationRobot(Protocol):
    """What the procedure needs of the arm and the camera."""

    def move(self, q: NDArray[np.float64]) -> tuple[str, str]:
        """Move to the posture ``q`` (chain order) and wait until reached; ``("", "")``, or the
        refusal ``(kind, reason)``."""

    def joints(self) -> NDArray[np.float64]:
        """The measured chain posture (after the last move), rad."""

    def frame(self) -> NDArray[np.uint8]:
        """An RGB colour frame taken after the last move ended (H, W, 3)."""


@dataclass(frozen=True)
class CalibrationSetup:
    """What the procedure starts from.

    Attributes
    ----------
    mount : (4, 4) ndarray
        ``T_flange_board`` as designed (a few cm / degrees off is fine: it is solved for).
    camera : (4, 4) ndarray
        Guess of ``T_world_camera`` (optical frame), good enough to see the board.
    k : (3, 3) ndarray
        Camera matrix, px (``camera_info``).
    size : (width, height)
        Image size, px.
    d : tuple of float
        Distortion coefficients (``camera_info``; empty: none).
    poses : int
        Generated views after the first (the total stays within :data:`MAX_POSES`).
    seed : int
        Seed of the generated poses.
    board : BoardSpec
    solve : SolveConfig
    """

    mount: NDArray[np.float64]
    camera: NDArray[np.float64]
    k: NDArray[np.float64]
    size: tuple[int, int]
    d: tuple[float, ...] = ()
    poses: int = 15
    seed: int = 0
    board: BoardSpec = field(default_factory=BoardSpec)
    solve: SolveConfig = field(default_factory=SolveConfig)


@dataclass
class CalibrationOutcome:
    """A calibration's result and its record: the views, the poses moved to and dropped."""

    result: HandEyeResult
    views: list[View]
    moved: int
    dropped: list[str]


def pnp_pose(board: BoardSpec, ids: NDArray[np.int64], pixels: NDArray[np.float64],
             k: NDArray[np.float64], d: tuple[float, ...] = ()) -> NDArray[np.float64] | None:
    """``T_camera_board`` (4, 4) of one detection by planar PnP, or None."""
    if len(ids) < 4:
        return None
    ok, rvec, tvec = cv2.solvePnP(board.corners[ids], pixels, k,
                                  np.asarray(d, dtype=np.float64) if d else None,
                                  flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = cv2.Rodrigues(rvec)[0], np.asarray(tvec).ravel()
    return t


class _Session:
    """One calibration's moves and views (:func:`run_calibration`)."""

    def __init__(self, robot: CalibrationRobot, arm: ArmKinematics, setup: CalibrationSetup,
                 motion: MotionConfig, log: Callable[[str], None]) -> None:
        self.robot, self.arm, self.setup, self.motion, self.log = robot, arm, setup, motion, log
        self.reference = np.array(motion.reference_positions, dtype=float)
        rng = np.random.default_rng(setup.seed)
        margin = motion.limit_margin + 0.05
        self.restarts = [rng.uniform(arm.lower + margin, arm.upper - margin)
                         for _ in range(IK_RESTARTS)]
        self.views: list[View] = []
        self.moved = 0
        self.dropped: list[str] = []

    def posture(self, tool: NDArray[np.float64]) -> NDArray[np.float64] | str:
        """The checked posture for the flange pose ``tool``, or why there is none."""
        current = self.robot.joints()
        ik = pose_ik(self.arm, tool, [current, self.reference, *self.restarts], self.reference,
                     margin=self.motion.limit_margin, max_iterations=IK_ITERATIONS)
        if not ik.within(IK_TOLERANCE):
            return (f"ik: no posture ({ik.position_error * 1e3:.1f} mm, "
                    f"{np.degrees(ik.rotation_error):.1f} deg off)")
        try:
            plan_joint_goal(self.arm, self.motion, ik.q, current)
        except PushRefused as refusal:
            return f"{refusal.kind}: {refusal.reason}"
        return ik.q

    def visit(self, tool: NDArray[np.float64]) -> View | None:
        """Move to the pose and take a view; None when the pose was dropped."""
        q = self.posture(tool)
        if isinstance(q, str):
            self.dropped.append(q)
            return None
        self.moved += 1
        kind, reason = self.robot.move(q)
        if kind in ROBOT_KINDS:
            raise CalibrationRefused("robot", f"the executor refused the move ({kind}): "
                                     f"{reason}")
        if kind:
            self.dropped.append(f"{kind}: {reason}")
            return None
        ids, pixels = detect_board(self.setup.board, self.robot.frame())
        view = View(self.arm.frame_pose(self.robot.joints(), self.arm.tool.flange_link),
                    ids, pixels)
        self.views.append(view)
        self.log(f"pose {self.moved}: {len(ids)} corners")
        return view


def run_calibration(robot: CalibrationRobot, arm: ArmKinematics, setup: CalibrationSetup,
                    motion: MotionConfig, log: Callable[[str], None] = lambda _: None
                    ) -> CalibrationOutcome:
    """Calibrate the camera (module docstring).

    Parameters
    ----------
    robot : CalibrationRobot
    arm : ArmKinematics
        The executor's model (its URDF, ``base_pose`` and ``tool.flange_link``).
    setup : CalibrationSetup
    motion : MotionConfig
        The executor's motion parameters (limits, margins, heights).
    log : callable
        Called with one line per pose.

    Returns
    -------
    CalibrationOutcome

    Raises
    ------
    CalibrationRefused
        ``board``, ``degenerate``, ``residual``, ``robot`` or ``reach`` (module docstring).
    """
    s = setup
    session = _Session(robot, arm, s, motion, log)
    centre = s.board.corners.mean(axis=0)
    guess = None
    for tool in board_facing_poses(s.camera, s.mount, centre, s.k, s.size, 4 * FIRST_TRIES,
                                   seed=s.seed, tilt_deg=0.0):
        if session.moved >= FIRST_TRIES:
            break
        view = session.visit(tool)
        if view is not None:
            board = pnp_pose(s.board, view.ids, view.pixels, s.k, s.d)
            if board is not None and len(view.ids) >= s.solve.min_corners:
                guess = camera_guess(view.tool_pose, s.mount, board)
                break
    if guess is None:
        raise CalibrationRefused("board", f"the board was not seen from the first poses "
                                 "made for the camera's guessed pose "
                                 f"({session.moved} reached; dropped: "
                                 f"{'; '.join(session.dropped)[:200] or 'none'})")
    wanted = min(s.poses, MAX_POSES - session.moved)
    candidates = board_facing_poses(guess, s.mount, centre, s.k, s.size, 4 * wanted,
                                    seed=s.seed + 1)
    taken = 0
    for tool in candidates:
        if taken >= wanted or session.moved >= MAX_POSES:
            break
        taken += session.visit(tool) is not None
    if len(session.views) < s.solve.min_views:
        raise CalibrationRefused("reach", f"{len(session.views)} poses reached, fewer than "
                                 f"{s.solve.min_views}; dropped {len(session.dropped)}: "
                                 f"{'; '.join(session.dropped)[:200]}")
    result = solve_eye_to_hand(session.views, s.board.corners, s.k, s.d, s.solve)
    return CalibrationOutcome(result, session.views, session.moved, session.dropped)
