"""The QoS profiles of the topic table (docs/INTERFACES.md), defined once and used on both ends.

- :data:`SENSOR_QOS` ("sensor"): ``qos_profile_sensor_data``, best effort, volatile, depth 5:
  camera images (a lost frame is replaced by the next one);
- :data:`RELIABLE_QOS` ("reliable"): reliable, volatile, depth 10: commands, observations;
- :data:`LATCHED_QOS` ("latched"): reliable, transient local, depth 1: data a late subscriber
  needs (the outline, the camera extrinsics, the estimator's outputs, ``planner/status``);
  subscribers use it too (or :func:`latched_reader_qos`, the same with a deeper reader
  queue), otherwise they do not get the last sample;
- :data:`GOAL_QOS`: what a goal *sender* publishes ``goal_pose`` with: latched, so a
  ``planner_node`` started or restarted later still gets the last goal (the graph runner's
  client and ``pushbot``'s own goal sender use it; RViz's volatile "2D Goal Pose" still
  works: ``planner_node`` subscribes both ways, see its module docstring);
- :data:`CLOCK_QOS`: ``/clock`` of the sim bridge, reliable, volatile, keep last 1 (matches the
  best-effort clock subscription of rclpy/rclcpp nodes and reliable ones);
- :data:`JOINT_STATE_QOS`: the readers of ``/joint_states`` (push_executor_node,
  segmentation_node's self-filter): reliable, volatile, depth 500 (a second of a 500 Hz
  stream -- the simulated arm at 5x real time -- waits in the queue while a node plans a push,
  rather than being dropped: the executor needs the contact segment's samples).
"""

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

__all__ = ["CLOCK_QOS", "GOAL_QOS", "JOINT_STATE_QOS", "LATCHED_QOS", "RELIABLE_QOS",
           "SENSOR_QOS", "latched_reader_qos"]

SENSOR_QOS = qos_profile_sensor_data
RELIABLE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
GOAL_QOS = LATCHED_QOS
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
JOINT_STATE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=500,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE)


def latched_reader_qos(depth: int = 10) -> QoSProfile:
    """Subscriber side of a latched stream where every sample matters (the estimator outputs).

    Reliable + transient local, so a late subscriber gets the writer's last sample; a reader
    queue of ``depth`` so samples arriving between two spins are not overwritten (the writer's
    depth 1 bounds what a late joiner receives, not what a matched reader keeps).
    """
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(depth),
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)
