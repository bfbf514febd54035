"""ekf_node: EKF over the object pose, centre of mass, l and m (not implemented yet).

Placeholder: the node is tracked in issue 5. ``main()`` says so and exits with status 2; it
does not pretend to run. The contract below is the one fixed in ``docs/ARCHITECTURE.md``; the
filter itself will live in ``push_core`` (no ROS imports), this node being a thin wrapper.

Future contract
---------------
State ``x = (x, y, theta, c_x, c_y, l, m)``: object frame position (m) and orientation (rad)
in ``world``, COM offset in the ``object`` frame (m), limit-surface parameter ``l`` (m) and
pusher-object friction coefficient ``m``. Process model: the analytical pushing model driven by
the executed push; observation model: identity on (x, y, theta). theta is kept continuous
(not wrapped) for symmetric objects.

Subscribes (names relative and remappable except ``/clock``):

- ``perception/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; "reliable")
- ``perception/outline`` (sensor_msgs/PointCloud2, ``object`` frame, outward normals;
  "latched")
- ``pusher/executed`` (nav_msgs/Path, ``world``: pusher poses at push start and end; "reliable")
- ``/clock`` (rosgraph_msgs/Clock; ``use_sim_time: true``)

Publishes:

- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; "reliable")
- ``estimator/center_of_mass`` (geometry_msgs/PointStamped, ``object``; "reliable")
- ``estimator/state`` (std_msgs/Float64MultiArray; "reliable"): layout dim 0 label ``state``
  = ``x,y,theta,c_x,c_y,l,m`` (size 7), dim 1 label ``covariance_row_major`` (size 49); data =
  the 7 state values then the 7x7 covariance
- ``/tf`` world -> object (tf2_msgs/TFMessage; only where ``tf2_msgs`` is importable)
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; one status for this node)

Services: ``~/reset`` (std_srvs/srv/Trigger) starts a new episode.

Parameters: ``use_sim_time`` (true with sim_bridge); initial state and noise parameters are
added by issue 5 and documented in ``ros_ws/config/push_estimator.yaml``.
"""

from __future__ import annotations

import sys

NODE_NAME = 'ekf_node'
ISSUE = 5


def main(args: list[str] | None = None) -> None:
    """Report that the node does not exist yet and exit with status 2."""
    print(f'{NODE_NAME} is not implemented yet (tracked in issue {ISSUE})', file=sys.stderr)
    sys.exit(2)


if __name__ == '__main__':
    main()
