"""Images and camera info <-> arrays: the one image codec, with validation before reshaping.

Encodings: ``rgb8`` / ``bgr8`` (H, W, 3) uint8, ``rgba8`` / ``bgra8`` (H, W, 4) uint8 (the ZED
wrapper's colour, some drivers' RGBA), ``mono8`` (H, W) uint8 (the perception mask,
255 = object), ``32FC1`` (H, W) float32 (depth in metres along the optical axis, NaN = no
return: the sim bridge) and ``16UC1`` / ``mono16`` (depth in millimetres, 0 = no return: the
RealSense driver's ``aligned_depth_to_color``). Rows may be padded (``step >= width *
bytes_per_pixel``); ``is_bigendian`` selects the byte order; ``len(data) != height * step`` is
refused before any reshape (the cv_bridge pitfall). CameraInfo: K and the distortion (``plumb_bob``
with 5 coefficients, zero by default, or ``rational_polynomial`` with 8) are written; when
reading, a valid K (finite, fx, fy > 0, last row (0, 0, 1)) is required and the distortion is
read by its own rule (:func:`distortion_from_info`): never dropped without a word.

Reader rules (one per field; a message outside them raises ``ValueError`` naming the field,
before anything proportional to the claimed size is allocated):

- ``Image.width``, ``Image.height``: in ``[1, MAX_IMAGE_SIDE]`` (8192 px; a D415 gives 1280 x
  720, the simulator 640 x 480).
- ``Image.step`` / ``data``: ``step >= width * bytes_per_pixel``, ``len(data) == height *
  step``.
- ``CameraInfo.width``, ``height``: in ``[1, MAX_IMAGE_SIDE]``.
- ``CameraInfo.k``: finite, ``fx``, ``fy`` in ``[MIN_FOCAL_PX, MAX_FOCAL_PX]`` (1 px to 1e5
  px), last row (0, 0, 1), principal point within the image extended by
  ``PRINCIPAL_POINT_MARGIN`` (half the image size) on every side.
- ``CameraInfo.distortion_model`` / ``d``: ``plumb_bob`` with 5 coefficients (k1, k2, p1, p2,
  k3) or ``rational_polynomial`` with 8 (k1, k2, p1, p2, k3, k4, k5, k6), the OpenCV order;
  every coefficient finite and within ``MAX_DISTORTION`` in magnitude. An empty model with an
  empty or all-zero ``d`` is an ideal pinhole. Any other model (``equidistant``, a vendor's
  name) is refused with its name: the pixels of such a camera cannot be read as a pinhole's.
"""

from __future__ import annotations

import sys
from array import array

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import CameraInfo, Image

from push_ros.frames import CAMERA_FRAME

__all__ = [
    "MAX_FOCAL_PX",
    "MAX_IMAGE_SIDE",
    "MIN_FOCAL_PX",
    "PRINCIPAL_POINT_MARGIN",
    "camera_info_msg",
    "check_image_layout",
    "check_image_size",
    "DISTORTION_MODELS",
    "MAX_DISTORTION",
    "camera_matrix_from_info",
    "color_image_msg",
    "depth_image_msg",
    "depth_mm_image_msg",
    "distortion_from_info",
    "depth_to_metres",
    "image_to_array",
    "mask_image_msg",
    "rgb_image_msg",
]

#: Largest image side accepted when reading (Image and CameraInfo width and height), px.
MAX_IMAGE_SIDE = 8192
#: Range of the focal lengths fx, fy accepted when reading a CameraInfo, px.
MIN_FOCAL_PX = 1.0
MAX_FOCAL_PX = 1e5
#: The principal point may lie this fraction of the image size outside the image.
PRINCIPAL_POINT_MARGIN = 0.5

#: Distortion models read, with their number of coefficients (OpenCV's order).
DISTORTION_MODELS: dict[str, int] = {"plumb_bob": 5, "rational_polynomial": 8}
#: Largest magnitude of a distortion coefficient accepted when reading (real lenses: < 10).
MAX_DISTORTION = 1e3

#: Numpy dtype and channels of the encodings :func:`image_to_array` decodes.
_ENCODINGS: dict[str, tuple[np.dtype, int]] = {
    "rgb8": (np.dtype(np.uint8), 3),
    "bgr8": (np.dtype(np.uint8), 3),
    "rgba8": (np.dtype(np.uint8), 4),
    "bgra8": (np.dtype(np.uint8), 4),
    "mono8": (np.dtype(np.uint8), 1),
    "32FC1": (np.dtype(np.float32), 1),
    "16UC1": (np.dtype(np.uint16), 1),
    "mono16": (np.dtype(np.uint16), 1),
}


def rgb_image_msg(rgb: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """An ``rgb8`` ``sensor_msgs/Image`` (``step = 3 * W``) of an (H, W, 3) uint8 RGB array:
    :func:`color_image_msg` with ``encoding="rgb8"`` (its parameters and errors)."""
    return color_image_msg(rgb, stamp, "rgb8", frame_id)


#: Channel order of each colour encoding, as indices into R, G, B (alpha is added at 255).
_COLOR_ORDER = {"rgb8": (0, 1, 2), "bgr8": (2, 1, 0), "rgba8": (0, 1, 2), "bgra8": (2, 1, 0)}


def color_image_msg(rgb: np.ndarray, stamp: Time, encoding: str = "rgb8",
                    frame_id: str = CAMERA_FRAME) -> Image:
    """Build a colour ``sensor_msgs/Image`` in ``encoding`` from an RGB array.

    Parameters
    ----------
    rgb : (H, W, 3) uint8 ndarray
        Colour image, channels in R, G, B order.
    stamp : Time
        Capture time.
    encoding : str
        ``rgb8``, ``bgr8``, ``rgba8`` or ``bgra8`` (alpha 255: opaque).
    frame_id : str
        Frame of the image, by default the colour optical frame.

    Raises
    ------
    ValueError
        If the array is not (H, W, 3) uint8 with H, W > 0, or the encoding is another.
    """
    if encoding not in _COLOR_ORDER:
        raise ValueError(f"colour encoding must be one of {sorted(_COLOR_ORDER)}, got "
                         f"{encoding[:32]!r}")
    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8 or rgb.size == 0:
        raise ValueError(
            f"rgb image must be a non-empty (H, W, 3) uint8 array, got shape {rgb.shape} "
            f"dtype {rgb.dtype}"
        )
    pixels = rgb[:, :, list(_COLOR_ORDER[encoding])]
    if _ENCODINGS[encoding][1] == 4:
        pixels = np.concatenate([pixels, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)
    return _image_msg(pixels, encoding, stamp, frame_id)


def depth_mm_image_msg(depth: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """Build a ``16UC1`` depth image in millimetres (the RealSense / Orbbec drivers' unit).

    Parameters
    ----------
    depth : (H, W) float ndarray
        Depth along the optical axis, metres; NaN (no return) becomes 0, depth is rounded to
        the millimetre and clipped to [1, 65535] mm.
    stamp : Time
    frame_id : str

    Raises
    ------
    ValueError
        If the array is not 2-D, non-empty and floating point.
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(
            f"depth image must be a non-empty (H, W) float array, got shape {depth.shape} "
            f"dtype {depth.dtype}"
        )
    valid = np.isfinite(depth) & (depth > 0)
    mm = np.zeros(depth.shape, dtype="<u2")
    mm[valid] = np.clip(np.round(depth[valid] * 1e3), 1, 65535)
    return _image_msg(mm, "16UC1", stamp, frame_id)


def depth_image_msg(depth: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """Build a ``32FC1`` ``sensor_msgs/Image`` from a depth array.

    Parameters
    ----------
    depth : (H, W) float ndarray
        Depth along the optical axis (z of the optical frame), metres; NaN where there is no
        return.
    stamp : Time
        Capture time.
    frame_id : str
        Frame of the image, by default the colour optical frame (depth is aligned to colour).

    Returns
    -------
    Image
        ``encoding="32FC1"``, little-endian float32, ``step = 4 * W``.

    Raises
    ------
    ValueError
        If the array is not 2-D and non-empty.
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(
            f"depth image must be a non-empty (H, W) float array, got shape {depth.shape} "
            f"dtype {depth.dtype}"
        )
    return _image_msg(depth.astype("<f4", copy=False), "32FC1", stamp, frame_id)


def _image_msg(pixels: np.ndarray, encoding: str, stamp: Time, frame_id: str) -> Image:
    """Fill an Image with tightly packed rows of ``pixels`` (already in the wire dtype)."""
    height, width = pixels.shape[:2]
    pixels = np.ascontiguousarray(pixels)
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height = int(height)
    msg.width = int(width)
    msg.encoding = encoding
    order = pixels.dtype.byteorder
    msg.is_bigendian = int(order == ">" or (order == "=" and sys.byteorder == "big"))
    msg.step = int(pixels.strides[0])
    # array('B', bytes) is the setter's fast path (no per-element type checks).
    msg.data = array("B", pixels.tobytes())
    return msg


def image_to_array(msg: Image) -> np.ndarray:
    """Decode a ``sensor_msgs/Image`` into a numpy array, validating its layout first.

    Parameters
    ----------
    msg : Image
        Encoding ``rgb8``, ``bgr8``, ``mono8``, ``32FC1``, ``16UC1`` or ``mono16``; rows may be
        padded (``step >= width * bytes_per_pixel``).

    Returns
    -------
    ndarray
        (H, W, 3) uint8 for ``rgb8``/``bgr8`` (channel order as encoded), (H, W) uint8 for
        ``mono8``, (H, W) float32 / uint16 (native byte order) for ``32FC1`` / ``16UC1`` and
        ``mono16``. A copy, independent of the message.

    Raises
    ------
    ValueError
        For unsupported encodings, a size outside ``[1, MAX_IMAGE_SIDE]``, ``step`` smaller
        than a row, or ``len(data) != height * step``.
    """
    dtype, channels, row_bytes = check_image_layout(msg)
    wire = dtype.newbyteorder(">" if msg.is_bigendian else "<")
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)[:, :row_bytes]
    pixels = np.ascontiguousarray(rows).view(wire).astype(dtype.newbyteorder("="), copy=True)
    shape = (msg.height, msg.width, channels) if channels > 1 else (msg.height, msg.width)
    return pixels.reshape(shape)


def check_image_size(width: int, height: int, what: str = "image") -> None:
    """Raise ``ValueError`` unless ``1 <= width, height <= MAX_IMAGE_SIDE`` (px)."""
    for name, value in (("width", width), ("height", height)):
        if not 1 <= int(value) <= MAX_IMAGE_SIDE:
            raise ValueError(f"{what} {name} must be in [1, {MAX_IMAGE_SIDE}] px, got {value}")


def check_image_layout(msg: Image, encodings: tuple[str, ...] | None = None
                       ) -> tuple[np.dtype, int, int]:
    """Check an Image's encoding, size, ``step`` and ``len(data)`` without decoding it.

    Parameters
    ----------
    msg : Image
    encodings : tuple of str, optional
        The encodings the caller accepts (default: every one :func:`image_to_array` decodes).

    Returns
    -------
    (dtype, channels, row_bytes)
        Pixel dtype of the encoding, channels and bytes of one unpadded row.

    Raises
    ------
    ValueError
        Naming the field: ``encoding``, ``width``/``height`` (``[1, MAX_IMAGE_SIDE]``),
        ``step`` (smaller than a row) or ``data`` (``len(data) != height * step``).
    """
    allowed = tuple(_ENCODINGS) if encodings is None else encodings
    if msg.encoding not in allowed or msg.encoding not in _ENCODINGS:
        raise ValueError(
            f"unsupported image encoding {msg.encoding[:32]!r}; expected one of "
            f"{sorted(allowed)}"
        )
    check_image_size(msg.width, msg.height, "image")
    dtype, channels = _ENCODINGS[msg.encoding]
    row_bytes = msg.width * channels * dtype.itemsize
    if msg.step < row_bytes:
        raise ValueError(
            f"image step {msg.step} is smaller than one row ({msg.width} px * {channels} ch * "
            f"{dtype.itemsize} B = {row_bytes} B)"
        )
    if len(msg.data) != msg.height * msg.step:
        raise ValueError(
            f"image data has {len(msg.data)} bytes, expected height * step = "
            f"{msg.height} * {msg.step} = {msg.height * msg.step}"
        )
    return dtype, channels, row_bytes


def camera_info_msg(
    camera_matrix: np.ndarray, width: int, height: int, stamp: Time, frame_id: str = CAMERA_FRAME,
    distortion: np.ndarray | None = None, distortion_model: str = "plumb_bob",
) -> CameraInfo:
    """Build a ``sensor_msgs/CameraInfo`` (by default for an ideal pinhole camera).

    Parameters
    ----------
    camera_matrix : (3, 3) ndarray
        Intrinsics ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, pixels.
    width, height : int
        Image size, pixels.
    stamp : Time
        Stamp of the image this info belongs to.
    frame_id : str
        Optical frame, by default the colour optical frame.
    distortion : (N,) array, optional
        Distortion coefficients in OpenCV's order (:data:`DISTORTION_MODELS` gives N); None:
        zero (an ideal pinhole).
    distortion_model : str
        ``plumb_bob`` or ``rational_polynomial``.

    Returns
    -------
    CameraInfo
        ``distortion_model``, ``d`` (zeros by default), ``k = K``, ``r = I``,
        ``p = [K | 0]`` (monocular; the driver's rectified K is K), no binning or ROI.

    Raises
    ------
    ValueError
        If K is not a finite (3, 3) matrix with positive focal lengths and last row
        (0, 0, 1), the size is not positive, or the model or coefficients break the reader's
        rule (module docstring).
    """
    k = _check_camera_matrix(camera_matrix)
    if int(width) <= 0 or int(height) <= 0:
        raise ValueError(f"image size must be positive, got {width} x {height}")
    if distortion_model not in DISTORTION_MODELS:
        raise ValueError(f"distortion model must be one of {sorted(DISTORTION_MODELS)}, got "
                         f"{distortion_model[:32]!r}")
    n = DISTORTION_MODELS[distortion_model]
    d = np.zeros(n) if distortion is None else _check_distortion(distortion_model, distortion)
    msg = CameraInfo()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.width = int(width)
    msg.height = int(height)
    msg.distortion_model = distortion_model
    msg.d = [float(v) for v in d]
    msg.k = k.ravel().tolist()
    msg.r = np.eye(3).ravel().tolist()
    msg.p = np.hstack([k, np.zeros((3, 1))]).ravel().tolist()
    return msg


def camera_matrix_from_info(msg: CameraInfo) -> np.ndarray:
    """Return the (3, 3) intrinsics ``K`` of a ``CameraInfo``, validated.

    Parameters
    ----------
    msg : CameraInfo

    Returns
    -------
    (3, 3) float ndarray
        ``K``, pixels.

    Raises
    ------
    ValueError
        If K is not a valid pinhole matrix (see :func:`camera_info_msg`), or breaks a reader
        rule of the module docstring (image size, focal length range, principal point).
    """
    check_image_size(msg.width, msg.height, "camera_info")
    k = _check_camera_matrix(np.asarray(msg.k, dtype=float).reshape(3, 3))
    for name, value in (("fx", k[0, 0]), ("fy", k[1, 1])):
        if not MIN_FOCAL_PX <= value <= MAX_FOCAL_PX:
            raise ValueError(f"camera_info {name} must be in [{MIN_FOCAL_PX:g}, "
                             f"{MAX_FOCAL_PX:g}] px, got {value:g}")
    for name, value, size in (("cx", k[0, 2], msg.width), ("cy", k[1, 2], msg.height)):
        margin = PRINCIPAL_POINT_MARGIN * size
        if not -margin <= value <= size + margin:
            raise ValueError(f"camera_info principal point {name} = {value:g} px lies outside "
                             f"the {msg.width} x {msg.height} image (margin {margin:g} px)")
    return k


def distortion_from_info(msg: CameraInfo) -> tuple[str, np.ndarray]:
    """The distortion model and coefficients of a ``CameraInfo``, by the reader's rule.

    Parameters
    ----------
    msg : CameraInfo

    Returns
    -------
    model : str
        ``plumb_bob`` or ``rational_polynomial`` (an empty model with no or zero coefficients
        reads as ``plumb_bob`` with zeros).
    d : (5,) or (8,) float ndarray
        The coefficients in OpenCV's order (all zero: an ideal pinhole).

    Raises
    ------
    ValueError
        Naming the model or the coefficient count: another model (``equidistant``, a vendor
        name), a count that does not match the model, a coefficient not finite or larger than
        ``MAX_DISTORTION`` in magnitude.
    """
    model = str(msg.distortion_model)
    d = np.asarray(msg.d, dtype=float).ravel()
    if model == "" and (d.size == 0 or (np.all(np.isfinite(d)) and not np.any(d))):
        return "plumb_bob", np.zeros(DISTORTION_MODELS["plumb_bob"])
    if model not in DISTORTION_MODELS:
        raise ValueError(f"camera_info distortion_model {model[:32]!r} is not supported (read: "
                         f"{', '.join(sorted(DISTORTION_MODELS))}); its pixels cannot be "
                         "undistorted here, so the camera is refused rather than read as an "
                         "ideal pinhole")
    return model, _check_distortion(model, d)


def _check_distortion(model: str, coefficients: np.ndarray) -> np.ndarray:
    d = np.asarray(coefficients, dtype=float).ravel()
    n = DISTORTION_MODELS[model]
    if d.size != n:
        raise ValueError(f"camera_info {model} distortion needs {n} coefficients in d, got "
                         f"{d.size}")
    if not np.all(np.isfinite(d)) or np.any(np.abs(d) > MAX_DISTORTION):
        raise ValueError(f"camera_info distortion coefficients must be finite and within "
                         f"+-{MAX_DISTORTION:g}, got {d.tolist()}")
    return d


def _check_camera_matrix(camera_matrix: np.ndarray) -> np.ndarray:
    k = np.asarray(camera_matrix, dtype=float)
    if k.shape != (3, 3) or not np.all(np.isfinite(k)):
        raise ValueError(f"camera matrix must be a finite (3, 3) array, got shape {k.shape}")
    if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0.0, 0.0, 1.0]):
        raise ValueError(f"camera matrix must have fx, fy > 0 and last row (0, 0, 1), got {k}")
    return k


def mask_image_msg(mask: np.ndarray, stamp: Time, frame_id: str = CAMERA_FRAME) -> Image:
    """A ``mono8`` image of a boolean mask (255 = object, 0 = not), ``step = W``.

    Raises
    ------
    ValueError
        If the mask is not a non-empty 2-D array.
    """
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0:
        raise ValueError(f"mask must be a non-empty 2-D array, got shape {m.shape}")
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = (int(s) for s in m.shape)
    msg.encoding = "mono8"
    msg.is_bigendian = 0
    msg.step = msg.width
    msg.data = array("B", (m.astype(bool).astype(np.uint8) * 255).tobytes())
    return msg


def depth_to_metres(msg: Image) -> np.ndarray:
    """Depth image as float32 metres (H, W), NaN where there is no return.

    Parameters
    ----------
    msg : Image
        ``32FC1`` in metres (NaN, inf or <= 0 = no return), or ``16UC1`` / ``mono16`` in
        millimetres (0 = no return).

    Raises
    ------
    ValueError
        Other encodings, or a layout that does not match (``step``, ``len(data)``).
    """
    if msg.encoding in ("16UC1", "mono16"):
        mm = image_to_array(msg)
        depth = mm.astype(np.float32) * np.float32(1e-3)
        depth[mm == 0] = np.nan
        return depth
    if msg.encoding != "32FC1":
        raise ValueError(f"unsupported depth encoding {msg.encoding!r}; expected 32FC1 "
                         "(metres) or 16UC1 (millimetres)")
    depth = image_to_array(msg)
    depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
    return depth
