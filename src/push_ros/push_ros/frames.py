"""The frame names of the pipeline (docs/ARCHITECTURE.md#units-frames-conventions), defined once."""

__all__ = ["CAMERA_FRAME", "OBJECT_FRAME", "PUSHER_FRAME", "WORLD_FRAME"]

#: The table frame: origin on the table at the workspace centre, z up.
WORLD_FRAME = "world"
#: REP 103 optical frame of the colour camera (z forward, x right, y down); depth is aligned
#: to it (the RealSense driver's default name).
CAMERA_FRAME = "camera_color_optical_frame"
#: The object frame: origin at the area centroid, axes of the episode's first frame.
OBJECT_FRAME = "object"
#: On the pusher axis at table height.
PUSHER_FRAME = "pusher"
