"""Tool poses for a calibration: the board inside the camera's view, facing it, with rotation
spread about every axis.

The poses are made in the camera's frame, where "in view" is simple, from a rough guess of the
camera's pose and of the board's mounting (a few centimetres and degrees off are fine: the
poses only need to keep the board in the image; the solver finds both transforms). A guess of
the camera's pose comes from one view of the board (:func:`camera_guess`): the arm at any pose
where the board is seen, the board's pose in the camera by PnP, the mounting as designed.
Whether the arm can reach a pose is the executor's to check (it refuses the ones it cannot).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

__all__ = ["board_facing_poses", "camera_guess"]


def camera_guess(tool_pose: ArrayLike, mount: ArrayLike, camera_board: ArrayLike
                 ) -> NDArray[np.float64]:
    """``T_world_camera`` (4, 4) from one view: ``T_world_tool @ T_tool_board @
    inv(T_camera_board)`` (the tool pose by forward kinematics, the mounting as designed, the
    board in the camera by PnP)."""
    return (np.asarray(tool_pose, dtype=np.float64) @ np.asarray(mount, dtype=np.float64)
            @ np.linalg.inv(np.asarray(camera_board, dtype=np.float64)))


def board_facing_poses(world_camera: ArrayLike, mount: ArrayLike, board_centre: ArrayLike,
                       k: ArrayLike, size: tuple[int, int], n: int, seed: int, *,
                       depth: tuple[float, float] = (0.45, 0.6), tilt_deg: float = 20.0,
                       margin: float = 0.25) -> list[NDArray[np.float64]]:
    """``n`` tool poses ``T_world_tool`` that show the board to the camera.

    Pose ``i`` puts the board's centre on a camera ray through a random pixel of the image's
    central part (``margin`` of each side left out) at a random depth in ``depth``, the board
    facing the camera (its z along the optical axis) and then tilted by ``tilt_deg`` about an
    axis in the board plane or along its normal: the axes cycle through board x, board y and
    the normal with alternating sign (so the set spreads over all three, never one axis), with
    a random part of up to a third of the tilt about the other two.

    Parameters
    ----------
    world_camera : (4, 4) array
        Guess of ``T_world_camera`` (optical frame), m.
    mount : (4, 4) array
        Guess of ``T_tool_board``, m.
    board_centre : (3,) array
        The board's centre in the board frame, m.
    k : (3, 3) array
        Camera matrix, px.
    size : (width, height)
        Image size, px.
    n : int
        Number of poses.
    seed : int
        Seed of the random pixels, depths and tilt parts.

    Returns
    -------
    list of (4, 4) ndarray
        Tool poses in ``world``, m.
    """
    z = np.asarray(world_camera, dtype=np.float64)
    x = np.asarray(mount, dtype=np.float64)
    centre = np.asarray(board_centre, dtype=np.float64)
    kk = np.asarray(k, dtype=np.float64)
    rng = np.random.default_rng(seed)
    w, h = size
    poses = []
    for i in range(n):
        u = rng.uniform(margin * w, (1 - margin) * w)
        v = rng.uniform(margin * h, (1 - margin) * h)
        d = rng.uniform(*depth)
        target = np.array([(u - kk[0, 2]) / kk[0, 0], (v - kk[1, 2]) / kk[1, 1], 1.0]) * d
        axis = np.zeros(3)
        axis[i % 3] = 1.0 if (i // 3) % 2 == 0 else -1.0
        axis += rng.uniform(-1.0, 1.0, 3) / 3.0
        tilt = Rotation.from_rotvec(np.radians(tilt_deg) * axis / np.linalg.norm(axis))
        camera_board = np.eye(4)
        camera_board[:3, :3] = tilt.as_matrix()
        camera_board[:3, 3] = target - camera_board[:3, :3] @ centre
        poses.append(z @ camera_board @ np.linalg.inv(x))
    return poses
