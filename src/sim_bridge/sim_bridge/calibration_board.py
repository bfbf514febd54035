"""The calibration board on the simulated arm's tool, and the camera placed by parameters.

ROS-free. With ``WorldConfig.calibration_board`` the arm's URDF gains a visual-only fixed link
``calibration_board`` on the flange ``panda_link8``: a thin plate textured with the ChArUco
board of :class:`push_core.calibration.BoardSpec`, its printed face on the rod's side (down
while the rod points down, so it never shows while pushing), centred :data:`BOARD_OFFSET` off
the flange axis so the rod does not cross it. To show it, the arm points the tool at the
camera, the arm behind the board, where it hides nothing. It has
no collision geometry: it touches nothing and the robot filter of perception does not mask it.
The camera's calibration does not need to know where the board sits on the tool (it solves
for it); this module's :func:`board_mount` is the truth the tests compare with.

The plate is an OBJ mesh (one quad with texture coordinates; pybullet's box maps a texture
atlas, not the whole image, to each face) written with its PNG texture to a cache folder of
the process, named by the board's geometry, and kept for the process's life (the URDF on
``/robot_description`` names the mesh file).

Camera placement: ``WorldConfig.camera_pose`` (x, y, z, qx, qy, qz, qw: the optical frame in
``world``) replaces the look-at viewpoint of :class:`sim_bridge.camera.CameraConfig` when set;
the published extrinsics are that pose (the truth).
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from push_core.calibration import BoardSpec
from push_core.geometry import matrix_from_quaternion

__all__ = ["BOARD_JOINT", "BOARD_LINK", "BOARD_MASS", "BOARD_OFFSET", "add_board", "board_mount",
           "camera_pose_matrix", "texture_board"]

#: Name of the board's fixed link and joint in the URDF.
BOARD_LINK = "calibration_board"
BOARD_JOINT = "calibration_board_joint"
#: Centre of the plate in the flange frame, m: off the axis along flange x (the plate starts
#: 2.5 cm from the rod), 5 mm down the flange's z, the rod's side of the flange.
BOARD_OFFSET = (0.10, 0.0, 0.005)
#: Mass of the plate, kg (a 15 cm square of 3 mm aluminium composite).
BOARD_MASS = 0.1
#: Texture pixels per board square (a 30 mm square: 0.23 mm per texel, far below a camera
#: pixel at 0.5 m, so the texture's own sampling does not move the corners).
TEXELS_PER_SQUARE = 128


def board_mount(spec: BoardSpec) -> NDArray[np.float64]:
    """``T_flange_board`` (4, 4): the board frame (:mod:`push_core.calibration.charuco`) in
    the flange frame: the board's z is the flange's -z (and its y the flange's -y), so a
    viewer looking against the flange's z, from the rod's side, sees the printed face."""
    w, h = spec.size
    rot = np.diag([1.0, -1.0, -1.0])
    t = np.eye(4)
    t[:3, :3] = rot
    t[:3, 3] = np.asarray(BOARD_OFFSET) - rot @ np.array([w / 2, h / 2, 0.0])
    return t


def _cache(spec: BoardSpec) -> tuple[Path, Path]:
    key = hashlib.sha1(f"{spec!r} {BOARD_OFFSET} {TEXELS_PER_SQUARE} 3".encode()).hexdigest()[:12]
    folder = Path(tempfile.gettempdir()) / f"pushbot-board-{os.getuid()}-{key}"
    mesh, texture = folder / "board.obj", folder / "board.png"
    if not (mesh.is_file() and texture.is_file()):
        folder.mkdir(parents=True, exist_ok=True)
        corners = board_mount(spec) @ np.array([[x, y, 0.0, 1.0] for x, y in
                                                [(0, 0), (spec.size[0], 0), spec.size,
                                                 (0, spec.size[1])]]).T
        # Texture v runs up the image (OBJ convention): board y = 0 is the image's top row.
        uv = [(0, 1), (1, 1), (1, 0), (0, 0)]
        normal = board_mount(spec)[:3, :3] @ np.array([0.0, 0.0, -1.0])  # towards the viewer
        lines = [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in corners[:3].T]
        # Counter-clockwise seen from the printed side (the renderer culls back faces).
        lines += [f"vt {u} {v}" for u, v in uv] + ["vn {:g} {:g} {:g}".format(*normal),
                                                   "f 1/1/1 3/3/1 2/2/1", "f 1/1/1 4/4/1 3/3/1"]
        tmp = folder / f"board.{os.getpid()}.tmp"
        tmp.write_text("\n".join(lines) + "\n")
        os.replace(tmp, mesh)
        cv2.imwrite(str(folder / f"board.{os.getpid()}.png"), spec.image(TEXELS_PER_SQUARE))
        os.replace(folder / f"board.{os.getpid()}.png", texture)
    return mesh, texture


def add_board(urdf: str, spec: BoardSpec) -> str:
    """``urdf`` (the arm's) with the board's visual-only link fixed on ``panda_link8``, of
    :data:`BOARD_MASS` at its centre (without an inertial pybullet gives a link 1 kg, which
    the simulated wrist could not track the executor's joint-space moves with)."""
    mesh, _ = _cache(spec)
    x, y, z = BOARD_OFFSET
    link = f"""  <link name="{BOARD_LINK}">
    <inertial>
      <origin rpy="0 0 0" xyz="{x} {y} {z}"/>
      <mass value="{BOARD_MASS}"/>
      <inertia ixx="1e-4" ixy="0" ixz="0" iyy="1e-4" iyz="0" izz="2e-4"/>
    </inertial>
    <visual>
      <origin rpy="0 0 0" xyz="0 0 0"/>
      <geometry><mesh filename="{mesh}"/></geometry>
    </visual>
  </link>
  <joint name="{BOARD_JOINT}" type="fixed">
    <parent link="panda_link8"/>
    <child link="{BOARD_LINK}"/>
    <origin rpy="0 0 0" xyz="0 0 0"/>
  </joint>
</robot>
"""
    end = urdf.rindex("</robot>")
    return urdf[:end] + link


def texture_board(client, body: int, spec: BoardSpec) -> None:
    """Put the board's texture on its link of ``body`` (after loading :func:`add_board`'s
    URDF); ``ValueError`` if the body has no such link."""
    links = {client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))}
    if BOARD_JOINT not in links:
        raise ValueError(f"the arm has no {BOARD_LINK} link")
    _, texture = _cache(spec)
    tex = client.loadTexture(str(texture))
    client.changeVisualShape(body, links[BOARD_JOINT], textureUniqueId=tex,
                             rgbaColor=[1, 1, 1, 1], specularColor=[0, 0, 0])


def camera_pose_matrix(pose: ArrayLike) -> NDArray[np.float64]:
    """``T_world_camera`` (4, 4) of (x, y, z, qx, qy, qz, qw) (m; a unit quaternion)."""
    v = np.asarray(pose, dtype=np.float64).ravel()
    if v.shape != (7,) or not np.all(np.isfinite(v)):
        raise ValueError(f"camera_pose: expected 7 finite numbers (x, y, z, qx, qy, qz, qw), "
                         f"got {v.size}")
    t = np.eye(4)
    t[:3, :3] = matrix_from_quaternion(v[3:])
    t[:3, 3] = v[:3]
    return t
