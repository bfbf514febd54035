"""The robot as the camera sees it: its URDF geometry posed by the joints and rendered.

ROS-free (numpy, scipy, pinocchio ``pin``); no simulator, no OpenGL. Perception uses it to
remove the robot's own pixels from a frame (the idea of MoveIt's depth self-filter and of
``robot_self_filter``), the executor to choose arm poses clear of the object's silhouette.
This package's top level is its public face::

    from push_core.robot_view import RobotGeometry, prism_silhouette

    robot = RobotGeometry.from_urdf(urdf_text, package_dirs=[...], base_pose=(x, y, z, yaw))
    poses = robot.link_poses(joint_names, positions)          # {link: T_world_link (4, 4)}
    mask, depth = robot.render(K, T_world_camera, 640, 480, joint_names, positions,
                               dilate_px=2)
    seen = prism_silhouette(outline, thickness, K, inv(T_world_camera), 640, 480)
    hidden = (mask & seen).sum() / seen.sum()  # the share of the object the robot hides

Frames and conventions (REP 103: metres, radians, right-handed, z up):

- ``world``: the table frame of the pipeline. The URDF link ``base_link`` (default: the root
  link) stands at ``base_pose`` = (x, y, z, yaw) in ``world``, as push_executor's
  ``base_pose`` parameter.
- The camera: ``T_world_camera`` (4, 4) maps points of its REP 103 optical frame (z forward,
  x right, y down) to ``world``; pixels follow OpenCV (``u`` right, ``v`` down, integer
  coordinates at pixel centres, ``(u, v, 1) ~ K p``); depth is the optical z, not the ray
  length. These are the conventions of the pipeline's RGB-D frames.
- Joint positions are given by name (a ``sensor_msgs/JointState``'s names and positions;
  extra names are ignored, a missing joint of the model is an error): rad for revolute and
  continuous joints, m for prismatic ones.

Modules: :mod:`push_core.robot_view.model` (:class:`RobotGeometry`: URDF, forward kinematics,
posed triangles, :meth:`RobotGeometry.render`), :mod:`push_core.robot_view.meshes` (shapes
to triangles), :mod:`push_core.robot_view.raster` (the z-buffer rasteriser). Work per frame is
bounded: at most ``MAX_TRIANGLES`` triangles, a bounded rasterisation
(:func:`push_core.robot_view.raster.rasterize`). Speed: docs/RESULTS.md, section
``bench_robot_view``; accuracy against the simulator's own render: tests/sim/test_robot_view.py.
"""

from __future__ import annotations

from push_core.robot_view.model import (
    MAX_DILATE_PX,
    MAX_TRIANGLES,
    MAX_URDF_CHARS,
    SIM_PANDA_BASE_POSE,
    RobotGeometry,
    RobotImage,
    base_transform,
    check_rigid_transform,
    dilate,
    joint_positions,
)
from push_core.robot_view.raster import check_camera, fill_polygon, prism_silhouette, rasterize

__all__ = ["MAX_DILATE_PX", "MAX_TRIANGLES", "MAX_URDF_CHARS", "SIM_PANDA_BASE_POSE",
           "RobotGeometry", "RobotImage",
           "base_transform", "check_camera", "check_rigid_transform", "dilate", "fill_polygon",
           "joint_positions", "prism_silhouette", "rasterize"]
