"""push_ros: the ROS-side library every pushbot node uses (no simulator, no pybullet).

Layering: ``push_core`` (ROS-free science) <- ``push_ros`` <- the node packages
(``sim_bridge``, ``push_perception``, ``push_estimator``, ``push_planner``). Modules:

- :mod:`push_ros.frames`: the frame names (``world``, the camera optical frame, ``object``,
  ``pusher``), defined once;
- :mod:`push_ros.qos`: the QoS profiles of the topic table ("sensor", "reliable",
  "latched", the ``/clock`` profile);
- message codecs, one per message, each writer with its checked reader:
  :mod:`push_ros.stamps` (``builtin_interfaces/Time``), :mod:`push_ros.poses` (quaternion,
  Pose, PoseStamped, PoseWithCovarianceStamped, PointStamped, TransformStamped),
  :mod:`push_ros.images` (Image rgb8/bgr8/mono8/32FC1/16UC1, CameraInfo),
  :mod:`push_ros.paths` (``nav_msgs/Path``: push commands, executed pushes),
  :mod:`push_ros.outline` (the ``perception/outline`` PointCloud2),
  :mod:`push_ros.state` (the ``estimator/state`` Float64MultiArray),
  :mod:`push_ros.diagnostics` (DiagnosticStatus / DiagnosticArray);
- :mod:`push_ros.node`: parameter table -> descriptors -> typed frozen config (validated at
  start-up and on every set), the one ``main()`` runner, throttled logging;
- :mod:`push_ros.interfaces`: docs/INTERFACES.md's parameter tables and the bundled parameter
  files, generated from the nodes' parameter tables.

Every reader raises ``ValueError`` whose message names the offending field, and
:class:`NonFiniteError` (a ``ValueError``) when the problem is a NaN or infinite value, so a node
can count the two kinds separately. Pure maths (quaternions, rotations) is in
:mod:`push_core.geometry`. Conventions: SI units, REP 103, quaternions (x, y, z, w).

The package imports nothing heavy at the top level: import the module you need.
"""

from push_core.geometry import NonFiniteError

__all__ = ["NonFiniteError"]
