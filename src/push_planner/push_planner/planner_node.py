"""planner_node: greedy affordance-based push planner (not implemented yet).

Placeholder: the node is tracked in issue 6. ``main()`` says so and exits with status 2; it
does not pretend to run. The contract below is the one fixed in ``docs/ARCHITECTURE.md``; the
planner itself will live in ``push_core`` (no ROS imports), this node being a thin wrapper.

Future contract
---------------
One push per cycle: score every outline point against the desired motion (goal minus current
estimate), sample contact points, optimise the push with rollouts of the analytical model, and
send the best push to the sim bridge.

Subscribes (names relative and remappable except ``/clock``):

- ``estimator/state`` (std_msgs/Float64MultiArray, layout as in ARCHITECTURE.md; "reliable")
- ``estimator/object_pose`` (geometry_msgs/PoseWithCovarianceStamped, ``world``; "reliable")
- ``perception/outline`` (sensor_msgs/PointCloud2, ``object`` frame, outward normals;
  "latched")
- ``goal_pose`` (geometry_msgs/PoseStamped, ``world``; "reliable"; RViz "2D Goal Pose")
- ``/clock`` (rosgraph_msgs/Clock; ``use_sim_time: true``)

Publishes:

- ``planner/push`` (nav_msgs/Path, ``world``; "reliable"): 3 poses: approach point, contact
  point, end point
- ``planner/affordances`` (visualization_msgs/MarkerArray, ``world``; "reliable")
- ``planner/status`` (diagnostic_msgs/DiagnosticStatus; "latched"): ``message`` is waiting /
  pushing step n / goal reached / failed after max steps; ``values`` carry step, max_steps,
  state
- ``/diagnostics`` (diagnostic_msgs/DiagnosticArray; one status for this node)

Services: ``~/reset`` (std_srvs/srv/Trigger) starts a new episode.

Parameters: ``use_sim_time`` (true with sim_bridge); planner parameters (number of sampled
contact points, lambda, push lengths, tolerances) are added by issue 6 and documented in
``ros_ws/config/push_planner.yaml``.
"""

from __future__ import annotations

import sys

NODE_NAME = 'planner_node'
ISSUE = 6


def main(args: list[str] | None = None) -> None:
    """Report that the node does not exist yet and exit with status 2."""
    print(f'{NODE_NAME} is not implemented yet (tracked in issue {ISSUE})', file=sys.stderr)
    sys.exit(2)


if __name__ == '__main__':
    main()
