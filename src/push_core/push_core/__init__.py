"""push_core package."""

from push_core.geometry import array_namespace as array_namespace
from push_core.geometry import check_points as check_points
from push_core.geometry import check_polyline as check_polyline
from push_core.geometry import check_poses as check_poses
from push_core.geometry import check_vectors as check_vectors
from push_core.geometry import closest_point_on_polyline as closest_point_on_polyline
from push_core.geometry import object_to_world as object_to_world
from push_core.geometry import rot2 as rot2
from push_core.geometry import world_to_object as world_to_object
from push_core.geometry import wrap_angle as wrap_angle
from push_core.model import ALPHA_MAX as ALPHA_MAX
from push_core.model import ALPHA_MIN as ALPHA_MIN
from push_core.model import L_MAX as L_MAX
from push_core.model import L_MIN as L_MIN
from push_core.model import apply_twist as apply_twist
from push_core.model import predict_motion as predict_motion
from push_core.model import push_twist as push_twist
from push_core.model import representative_pushes as representative_pushes
from push_core.objects import ObjectSpec as ObjectSpec
from push_core.objects import library_names as library_names
from push_core.objects import load_object as load_object
from push_core.rollout import RolloutResult as RolloutResult
from push_core.rollout import rollout_push as rollout_push
from push_core.shapes import Ellipse as Ellipse
from push_core.shapes import Polygon as Polygon
