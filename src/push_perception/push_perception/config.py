"""``segmentation_node``'s parameters: the declared table and the typed, validated configuration.

:data:`PARAMETERS` is the one declaration of every parameter (name, default, description with
unit, bounds, read-only); the geometry ones set the field of the same name of
:class:`~push_perception.perception_config.PerceptionConfig`.
:meth:`SegmentationParams.from_values` builds the frozen configuration and raises
``ValueError`` naming the parameter. docs/INTERFACES.md and
``pushbot_bringup/config/push_perception.yaml`` are generated from the table
(:mod:`push_ros.interfaces`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import ParameterType

from push_core.robot_view import SIM_PANDA_BASE_POSE
from push_perception.perception_config import PerceptionConfig
from push_perception.robot_filter import RobotFilterConfig
from push_ros.interfaces import SIM_TIME
from push_ros.node import ParamSpec

__all__ = ["NODE_NAME", "PARAMETERS", "YAML_EXTRA", "YAML_HEADER", "YAML_NOTES",
           "SegmentationParams"]

_GEOMETRY = {f.name: f.default for f in dataclasses.fields(PerceptionConfig)}
_STRINGS = ParameterType.PARAMETER_STRING_ARRAY
PARAMETERS: tuple[ParamSpec, ...] = (
    ParamSpec("weights", "", "Segmentation network weights (.pt) written by `pushbot train "
              "segmentation`; empty = the bundled push_perception/models/segmentation.pt (model "
              "card: models/segmentation.md).", read_only=True),
    ParamSpec("torch_threads", 1, "torch intra-op threads for the CNN; 1 keeps the latency "
              "steady on a shared CPU.", (1, 16), read_only=True),
    ParamSpec("sync_queue", 5, "Stamps kept per camera stream while matching colour, depth and "
              "camera_info by identical header stamps; an image pair pushed out without its "
              "camera_info is reported.", (1, 100), read_only=True),
    ParamSpec("threshold", 0.5, "Probability above which a pixel is the object.",
              (0.01, 0.99), read_only=True),
    ParamSpec("min_coarse_cells", 3, "Smallest coarse CNN component accepted as the object, "
              "cells of 8 x 8 px at 640 x 480.", (1, 10000), read_only=True),
    ParamSpec("publish_mask", True, "Publish perception/mask (mono8) for every segmented "
              "frame."),
    ParamSpec("anchor_timeout", 5.0, "Restart recovery: seconds (steady clock) after start-up "
              "to wait for the estimator's latched estimator/outline and estimator/object_pose, "
              "so that a node restarted mid-episode matches its first frame against the "
              "episode's outline and keeps its yaw reference (frames wait meanwhile); nothing in "
              "time (a fresh graph) or ~/reset = a new reference; 0 = never re-anchor.",
              (0.0, 60.0), read_only=True),
    ParamSpec("robot_filter.enabled", False, "The robot may stand in the camera's view (an "
              "arm): each frame's robot pixels are computed from its model and /joint_states "
              "and never taken for the object; a frame whose robot pixels cannot be computed is "
              "not used (the reason on perception/occlusion and /diagnostics). False: no robot "
              "in view (the free pusher, or an arm parked out of view), nothing is "
              "subscribed.", read_only=True),
    ParamSpec("robot_filter.description_file", "", "URDF file of the robot; empty: subscribe "
              "/robot_description (std_msgs/String, transient local).", read_only=True),
    ParamSpec("robot_filter.package_dirs", None, "Folders searched for the URDF's mesh files: "
              "package://<pkg>/<path> as <dir>/<pkg>/<path>, a relative path as <dir>/<path> "
              "(absolute paths are read as they are).", read_only=True, type=_STRINGS),
    ParamSpec("robot_filter.base_link", "", "URDF link standing at robot_filter.base_pose; "
              "empty: the root link.", read_only=True),
    ParamSpec("robot_filter.base_pose", list(SIM_PANDA_BASE_POSE), "Pose of the base link in "
              "world: x, y, z (m), yaw (rad), as push_executor_node's base_pose; the default "
              "is the simulated Panda's.", read_only=True),
    ParamSpec("robot_filter.dilate_px", 2, "Margin grown around the rendered robot, pixels "
              "(calibration and joint-state latency).", (0, 20), read_only=True),
    ParamSpec("robot_filter.depth_margin", 0.01, "A pixel measured more than this nearer "
              "than the robot's model is not the robot (something in front of it), m.",
              (0.0, 0.5), read_only=True),
    ParamSpec("robot_filter.joint_state_tolerance", 0.1, "Largest time between a frame's "
              "stamp and the joint state used for it, s (interpolated between the states "
              "before and after when both are this close).", (0.001, 5.0), read_only=True),
    ParamSpec("robot_filter.still_tolerance", 2.0, "Largest age of the last joint state "
              "before a frame that shows the robot at rest (every joint slower than 0.01 rad/s, "
              "velocities given) and is not contradicted by a later one, s; used when no state "
              "is within robot_filter.joint_state_tolerance.", (0.0, 60.0), read_only=True),
    ParamSpec("max_occluded", _GEOMETRY["max_occluded"], "With robot_filter.enabled: a frame "
              "in which the robot hides more than this share of the object's predicted "
              "silhouette gives no pose (outcome occluded).", (0.0, 0.9)),
    ParamSpec("occlusion_margin_px", _GEOMETRY["occlusion_margin_px"], "With "
              "robot_filter.enabled: object boundary this close to the robot's pixels is the "
              "robot's edge, left out of the pose fit; the episode's first frame must keep the "
              "object this far from the robot, pixels.", (0, 20)),
    ParamSpec("resolution", _GEOMETRY["resolution"], "Cell size of the top-down "
              "(orthographic, world-aligned) view of the object, m (finer: the view falls apart "
              "between the pixels' footprints; coarser costs yaw accuracy).", (5e-4, 3e-3)),
    ParamSpec("min_height", _GEOMETRY["min_height"], "Mask points lower than this above the "
              "table (or than 40 % of the object's top height, whichever is larger) are table "
              "pixels and are dropped, m (below the object's thickness).", (0.0, 0.01)),
    ParamSpec("closing_radius", _GEOMETRY["closing_radius"], "Morphological closing of the "
              "top-down view, cells; closing_radius * resolution in [1, 10] mm: fills the gaps "
              "between the pixels' footprints (1.3-2 mm on the table at 640 x 480) without "
              "filling concavities.", (2, 10)),
    ParamSpec("outline_spacing", _GEOMETRY["outline_spacing"], "Distance between outline "
              "points, m (at most 1000 points: a longer outline is spaced wider).",
              (5e-4, 0.01)),
    ParamSpec("outline_smoothing", _GEOMETRY["outline_smoothing"], "Gaussian smoothing "
              "along the outline (standard deviation), m: removes the raster's staircase "
              "(normals) at the price of rounding corners by about this much.", (0.0, 0.01)),
    ParamSpec("outline_offset", _GEOMETRY["outline_offset"], "Extra outward offset of the "
              "outline (calibration), m.", (-0.005, 0.005)),
    ParamSpec("symmetry_tolerance", _GEOMETRY["symmetry_tolerance"], "Orientation minima "
              "within this chamfer cost of the best are symmetric equivalents; the one closest "
              "to the previous frame's angle is reported, m.",
              (0.0, 0.01)),
    ParamSpec("min_pixels", _GEOMETRY["min_pixels"], "Fewer mask pixels (with depth) than "
              "this: no pose.", (3, 10**7)),
    ParamSpec("min_valid_fraction", _GEOMETRY["min_valid_fraction"], "Smaller fraction of "
              "mask pixels with depth than this: no pose.", (0.0, 1.0)),
    ParamSpec("max_border_pixels", _GEOMETRY["max_border_pixels"], "More mask pixels than "
              "this on the image border: object out of view, no pose.", (0, 10**7)),
    ParamSpec("sigma_position", _GEOMETRY["sigma_position"], "Base standard deviation of x "
              "and y at 5000 mask pixels with full depth, m; grows with fewer pixels, missing "
              "depth and footprint mismatch (docs/design/perception.md).",
              (1e-6, 1.0)),
    ParamSpec("sigma_theta", _GEOMETRY["sigma_theta"], "Base standard deviation of the "
              "relative yaw, rad; grows likewise and with the residual of the rotation search "
              "beyond match_cost_floor.", (1e-6, math.pi)),
    ParamSpec("match_cost_floor", _GEOMETRY["match_cost_floor"], "Chamfer residual of a "
              "correct rotation match (raster and depth noise: about 0.3 mm on clean frames, "
              "0.6 mm with depth noise); only the excess widens the yaw's deviation, m.",
              (0.0, 0.01)),
)

#: The node's name: the top-level key of its parameter file.
NODE_NAME = "segmentation_node"
#: Written before the table in the parameter file (ROS declares it).
YAML_EXTRA = (SIM_TIME,)
#: Comment at the top of the bundled parameter file (pushbot_bringup/config/push_perception.yaml).
YAML_HEADER = """
Parameters of segmentation_node (package push_perception): CNN segmentation of the object,
its pose from mask + depth, the orientation relative to the episode's first frame and the
outline with normals (docs/design/perception.md; the table is also in
docs/INTERFACES.md). Values below are the defaults. Units SI (REP 103): metres, radians.

  pushbot run segmentation_node --ros-args --params-file \\
      src/pushbot_bringup/config/push_perception.yaml
  ros2 run push_perception segmentation_node --ros-args --params-file \\
      $(ros2 pkg prefix pushbot_bringup)/share/pushbot_bringup/config/push_perception.yaml
  (`ros2 launch pushbot_bringup pushbot.launch.py` loads this file and sets use_sim_time
  from sim:=true|false; with sim:=false it also remaps the camera topics to realsense2_camera's)

Read-only parameters are read at start-up; the geometry parameters (max_occluded to
match_cost_floor) are read at start-up and again by ~/reset (std_srvs/srv/Trigger), which
starts a new episode. A bad value stops start-up with a clear message and a non-zero exit (a
refused reset keeps the previous values). Doubles need a decimal point (0.0, not 0)."""
#: Comment paragraphs before a parameter in the parameter file.
YAML_NOTES = {
    "weights": "The CNN and the node.",
    "robot_filter.enabled": "The robot in the camera's view (push_perception.robot_filter).",
    "max_occluded": "From mask to state (push_perception.perception_config.PerceptionConfig).",
}
_GEOMETRY_NAMES = tuple(n for n in _GEOMETRY if any(p.name == n for p in PARAMETERS))


@dataclass(frozen=True)
class SegmentationParams:
    """The node's parameters, typed and validated (see ``PARAMETERS`` for units).

    Attributes
    ----------
    weights : str
        Weights file; "" = bundled.
    torch_threads, sync_queue, min_coarse_cells : int
    threshold : float
    publish_mask : bool
    geometry : PerceptionConfig
        The mask-to-state parameters.
    anchor_timeout : float
        Seconds to wait for a re-anchoring after start-up (module docstring).
    robot_filter : RobotFilterConfig or None
        The self-filter's settings; None: ``robot_filter.enabled`` is false.
    description_file : str
        ``robot_filter.description_file``.
    """

    weights: str
    torch_threads: int
    sync_queue: int
    threshold: float
    min_coarse_cells: int
    publish_mask: bool
    geometry: PerceptionConfig
    anchor_timeout: float = 5.0
    robot_filter: RobotFilterConfig | None = None
    description_file: str = ""

    @classmethod
    def from_values(cls, values: dict[str, Any]) -> SegmentationParams:
        """Build from ``{name: value}``; raises ``ValueError`` naming a bad parameter."""
        geometry = {n: values[n] for n in _GEOMETRY_NAMES}
        try:
            config = PerceptionConfig(**geometry)
        except ValueError as exc:
            raise ValueError(f"invalid geometry parameter: {exc}") from None
        robot = None
        if values["robot_filter.enabled"]:
            robot = RobotFilterConfig(
                base_pose=tuple(values["robot_filter.base_pose"]),
                base_link=str(values["robot_filter.base_link"]),
                package_dirs=tuple(values["robot_filter.package_dirs"] or ()),
                dilate_px=int(values["robot_filter.dilate_px"]),
                depth_margin=float(values["robot_filter.depth_margin"]),
                joint_state_tolerance=float(values["robot_filter.joint_state_tolerance"]),
                still_tolerance=float(values["robot_filter.still_tolerance"]))
        return cls(weights=str(values["weights"]), torch_threads=int(values["torch_threads"]),
                   sync_queue=int(values["sync_queue"]), threshold=float(values["threshold"]),
                   min_coarse_cells=int(values["min_coarse_cells"]),
                   publish_mask=bool(values["publish_mask"]), geometry=config,
                   anchor_timeout=float(values["anchor_timeout"]), robot_filter=robot,
                   description_file=str(values["robot_filter.description_file"]))
