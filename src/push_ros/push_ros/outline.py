"""The ``perception/outline`` PointCloud2: its one writer and its checked reader.

Wire format (the writer defines it): an unorganised cloud (height 1, width K), little-endian,
``point_step`` 24, ``row_step`` 24 K, dense; float32 fields :data:`OUTLINE_FIELDS` = ``x, y, z,
normal_x, normal_y, normal_z`` at offsets 0, 4, ..., 20, z = normal_z = 0; frame ``object``;
points counter-clockwise along the outline (a closed polyline) with outward unit normals. The
reader also takes any other layout of the same fields (offsets from ``fields``, padded rows,
big-endian). NaN or infinite coordinates raise :class:`~push_ros.NonFiniteError`.
"""

from __future__ import annotations

from array import array

import numpy as np
from builtin_interfaces.msg import Time
from numpy.typing import ArrayLike, NDArray
from sensor_msgs.msg import PointCloud2, PointField

from push_core.geometry import NonFiniteError
from push_ros.frames import OBJECT_FRAME

__all__ = ["OUTLINE_FIELDS", "decimate_outline", "outline_cloud_msg", "outline_from_cloud"]

#: Field names of the outline cloud, all float32, in this order.
OUTLINE_FIELDS = ("x", "y", "z", "normal_x", "normal_y", "normal_z")


def outline_cloud_msg(points: ArrayLike, normals: ArrayLike, stamp: Time | None = None,
                      frame_id: str = OBJECT_FRAME) -> PointCloud2:
    """The outline as ``perception/outline``: an unorganised ``PointCloud2``.

    The wire format (this writer defines it; :func:`outline_from_cloud` reads it back): height
    1, width K, little-endian, ``point_step`` 24, ``row_step`` 24 K, dense; the float32 fields
    :data:`OUTLINE_FIELDS` at offsets 0, 4, ..., 20, with z = normal_z = 0.

    Parameters
    ----------
    points, normals : array_like, shape (K, 2)
        Outline points (metres) and outward unit normals in ``frame_id``, counter-clockwise.
        Any K >= 0 is written (an outline of fewer than 3 points is refused by the reader, not
        here, so tests can publish one).
    stamp : builtin_interfaces/Time, optional
        ``header.stamp``; None leaves it zero.
    frame_id : str
        ``header.frame_id``.

    Returns
    -------
    sensor_msgs/PointCloud2

    Raises
    ------
    ValueError
        If points and normals are not (K, 2) arrays of the same shape, or hold NaN or infinity.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != n.shape:
        raise ValueError(f"outline points and normals must both be (K, 2), got {p.shape} and "
                         f"{n.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise ValueError("outline points and normals must be finite")
    data = np.zeros((len(p), len(OUTLINE_FIELDS)), dtype="<f4")
    data[:, 0:2] = p
    data[:, 3:5] = n
    msg = PointCloud2()
    if stamp is not None:
        msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = 1, len(p)
    msg.fields = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(OUTLINE_FIELDS)]
    msg.is_bigendian = False
    msg.point_step = 4 * len(OUTLINE_FIELDS)
    msg.row_step = msg.point_step * len(p)
    msg.is_dense = True
    msg.data = array("B", data.tobytes())
    return msg


def outline_from_cloud(msg: PointCloud2, frame_id: str = OBJECT_FRAME,
                       max_points: int | None = None
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Outline points and outward normals of ``perception/outline``, checked.

    Accepts the format of :func:`outline_cloud_msg` and any other layout of the same fields:
    offsets are read from ``fields`` (other fields and padding are skipped), rows may be padded
    (``row_step > width * point_step``), and ``is_bigendian`` selects the byte order.

    Parameters
    ----------
    msg : sensor_msgs/PointCloud2
        Fields :data:`OUTLINE_FIELDS`, each FLOAT32 with count 1; points ordered
        counter-clockwise along the outline (not checked here).
    frame_id : str
        The required ``header.frame_id``.
    max_points : int, optional
        A cloud of more points (``width * height``) is refused before anything is decoded
        (bounded work and memory per message); None: no bound.

    Returns
    -------
    points, normals : numpy.ndarray, shape (K, 2)
        x, y of each point and of its normal, float64; z and normal_z are ignored.

    Raises
    ------
    NonFiniteError
        A NaN or infinite x, y, normal_x or normal_y (the only problem of the cloud).
    ValueError
        Every other problem, named in the message: a wrong ``header.frame_id``; a missing
        field, one that is not FLOAT32 with count 1, or one whose offset does not fit
        ``point_step``; an empty cloud, one of fewer than 3 points or of more than
        ``max_points``; ``row_step`` smaller than
        ``width * point_step``; ``data`` not ``row_step * height`` bytes long.
    """
    if msg.header.frame_id != frame_id:
        raise ValueError(f"header.frame_id is {msg.header.frame_id!r}, expected {frame_id!r}")
    fields = {f.name: f for f in msg.fields}
    for name in OUTLINE_FIELDS:
        f = fields.get(name)
        if f is None:
            raise ValueError(f"fields: missing {name!r} (need {', '.join(OUTLINE_FIELDS)}; "
                             f"got {', '.join(sorted(fields)) or 'none'})")
        if f.datatype != PointField.FLOAT32 or f.count != 1:
            raise ValueError(f"fields: {name!r} must be FLOAT32 with count 1, got datatype "
                             f"{f.datatype} count {f.count}")
        if f.offset + 4 > msg.point_step:
            raise ValueError(f"fields: {name!r} at offset {f.offset} does not fit point_step "
                             f"{msg.point_step}")
    count = int(msg.width) * int(msg.height)
    if count == 0:
        raise ValueError("the outline is empty: the cloud has no points (width * height = 0)")
    if count < 3:
        raise ValueError(f"the outline has {count} points, need >= 3")
    if max_points is not None and count > max_points:
        raise ValueError(f"the outline has {count} points, more than the {max_points} accepted")
    if msg.row_step < msg.width * msg.point_step:
        raise ValueError(f"row_step {msg.row_step} is smaller than width * point_step = "
                         f"{msg.width} * {msg.point_step}")
    if len(msg.data) != msg.row_step * msg.height:
        raise ValueError(f"data buffer has {len(msg.data)} bytes, expected row_step * height = "
                         f"{msg.row_step} * {msg.height} = {msg.row_step * msg.height}")
    raw = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.row_step)
    rows = raw[:, :msg.width * msg.point_step].reshape(count, msg.point_step)
    order = ">f4" if msg.is_bigendian else "<f4"

    def column(name: str) -> NDArray[np.float64]:
        off = fields[name].offset
        return np.ascontiguousarray(rows[:, off:off + 4]).view(order)[:, 0].astype(np.float64)

    points = np.stack([column("x"), column("y")], axis=1)
    normals = np.stack([column("normal_x"), column("normal_y")], axis=1)
    bad = ~(np.all(np.isfinite(points), axis=1) & np.all(np.isfinite(normals), axis=1))
    if np.any(bad):
        raise NonFiniteError(f"the outline has NaN or infinite coordinates ({int(bad.sum())} "
                             f"of {count} points, the first at index {int(np.argmax(bad))})")
    return points, normals


def decimate_outline(points: ArrayLike, normals: ArrayLike, max_points: int
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """At most ``max_points`` of an outline: every k-th point (and its normal) from the first,
    ``k = ceil(K / max_points)``; an outline of at most ``max_points`` is returned unchanged.

    Bounds the work of consumers whose cost grows faster than linearly with the outline (the
    estimator's polygon checks). Keeps the order (counter-clockwise stays counter-clockwise).

    Raises
    ------
    ValueError
        ``max_points < 3`` or points and normals that are not (K, 2) arrays of one shape.
    """
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2 or p.shape != n.shape:
        raise ValueError(f"outline points and normals must both be (K, 2), got {p.shape} and "
                         f"{n.shape}")
    if max_points < 3:
        raise ValueError(f"max_points must be >= 3, got {max_points}")
    if len(p) <= max_points:
        return p, n
    k = -(-len(p) // max_points)
    return p[::k].copy(), n[::k].copy()
