"""segmentation_node: object mask, pose and outline from the RGB-D camera (not implemented yet).

Placeholder: the node is tracked in issue 4. ``main()`` says so and exits with status 2; it
does not pretend to run. The contract below is the one fixed in ``docs/ARCHITECTURE.md``.

Future contract
---------------
Subscribes (all names relative and remappable except ``/clock``):

- ``camera/color/image_raw`` (sensor_msgs/Image, rgb8; "sensor" QoS)
- ``camera/aligned_depth_to_color/image_raw`` (sensor_msgs/Image, 32FC1 metres, NaN where there
  is no return; "sensor" QoS)
- ``camera/color/camera_info`` (sensor_msgs/CameraInfo, plumb_bob, zero distortion; "sensor")
- ``camera/color/extrinsics`` (geometry_msgs/TransformStamped, world ->
  camera_color_optical_frame; "latched" QoS)
- ``/clock`` (rosgraph_msgs/Clock; ``use_sim_time: true``)

Publishes:

- ``perception/mask`` (sensor_msgs/Image, mono8, frame camera_color_optical_frame; "sensor")
- ``perception/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, frame ``world``;
  "reliable"): position = centre of the mask's points deprojected with depth and intrinsics;
  orientation relative to the first frame of the episode (quaternion x, y, z, w)
- ``perception/outline`` (sensor_msgs/PointCloud2 with float32 x, y, z, normal_x, normal_y,
  normal_z, frame ``object``; "latched"): the outline counter-clockwise as a closed polyline,
  outward unit normals
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; one status for this node)

Services: ``~/reset`` (std_srvs/srv/Trigger) starts a new episode (new reference frame for the
relative orientation, new outline).

Parameters: ``use_sim_time`` (true with sim_bridge); the others are added by issue 4 and
documented in ``ros_ws/config/push_perception.yaml``.

Frames: ``camera_color_optical_frame`` (REP 103 optical), ``world`` (table), ``object``.
QoS names ("sensor", "reliable", "latched") as defined in ARCHITECTURE.md.
"""

from __future__ import annotations

import sys

NODE_NAME = 'segmentation_node'
ISSUE = 4


def main(args: list[str] | None = None) -> None:
    """Report that the node does not exist yet and exit with status 2."""
    print(f'{NODE_NAME} is not implemented yet (tracked in issue {ISSUE})', file=sys.stderr)
    sys.exit(2)


if __name__ == '__main__':
    main()
