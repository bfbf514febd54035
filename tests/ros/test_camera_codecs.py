"""push_ros.images for the camera drivers' messages: each colour encoding, each depth unit, each
distortion model read, and each one refused with its reason (never dropped without a word)."""

from __future__ import annotations

import numpy as np
import pytest
from builtin_interfaces.msg import Time

from push_perception.inputs import InputError, rgb_from_color
from push_ros.images import (
    camera_info_msg,
    color_image_msg,
    depth_image_msg,
    depth_mm_image_msg,
    depth_to_metres,
    distortion_from_info,
    image_to_array,
)

STAMP = Time(sec=3, nanosec=4)
K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8"])
def test_each_colour_encoding_reads_back_as_rgb(encoding: str) -> None:
    rgb = np.random.default_rng(1).integers(0, 256, (6, 5, 3), dtype=np.uint8)
    msg = color_image_msg(rgb, STAMP, encoding)
    channels = 4 if encoding.endswith("a8") else 3
    assert (msg.encoding, msg.step, len(msg.data)) == (encoding, 5 * channels, 30 * channels)
    pixels = image_to_array(msg)
    assert pixels.shape == (6, 5, channels)
    if encoding.startswith("bgr"):
        np.testing.assert_array_equal(pixels[:, :, 0], rgb[:, :, 2])  # stored blue first
    if channels == 4:
        assert np.all(pixels[:, :, 3] == 255)
    np.testing.assert_array_equal(rgb_from_color(pixels, encoding), rgb)


def test_colour_refusals_name_the_encoding_and_the_shape() -> None:
    with pytest.raises(InputError, match="yuv422"):
        rgb_from_color(np.zeros((2, 2, 2), np.uint8), "yuv422")
    with pytest.raises(InputError, match=r"\(H, W, 4\) for bgra8"):
        rgb_from_color(np.zeros((2, 2, 3), np.uint8), "bgra8")
    with pytest.raises(ValueError, match="colour encoding"):
        color_image_msg(np.zeros((2, 2, 3), np.uint8), STAMP, "mono8")


def test_depth_in_millimetres_and_in_metres_read_as_metres() -> None:
    depth = np.array([[0.8004, np.nan], [0.0, 1.25]], dtype=np.float32)
    mm = depth_mm_image_msg(depth, STAMP)
    assert mm.encoding == "16UC1" and image_to_array(mm).tolist() == [[800, 0], [0, 1250]]
    np.testing.assert_allclose(depth_to_metres(mm), [[0.8, np.nan], [np.nan, 1.25]], atol=1e-7)
    m = depth_to_metres(depth_image_msg(depth, STAMP))
    np.testing.assert_array_equal(np.isnan(m), [[False, True], [True, False]])
    assert m[0, 0] == np.float32(0.8004)


@pytest.mark.parametrize(("model", "d"), [
    ("plumb_bob", [0.08, -0.12, 0.001, -0.0006, 0.03]),
    ("rational_polynomial", [0.08, -0.12, 0.0006, -0.0004, 0.03, 0.01, -0.02, 0.01])])
def test_each_distortion_model_is_read_with_its_coefficients(model: str, d: list[float]) -> None:
    msg = camera_info_msg(K, 640, 480, STAMP, distortion=np.array(d), distortion_model=model)
    read_model, read_d = distortion_from_info(msg)
    assert read_model == model
    np.testing.assert_array_equal(read_d, d)


def test_an_ideal_pinhole_reads_as_zero_distortion() -> None:
    msg = camera_info_msg(K, 640, 480, STAMP)
    assert distortion_from_info(msg)[0] == "plumb_bob" and not distortion_from_info(msg)[1].any()
    msg.distortion_model, msg.d = "", []  # some drivers leave both empty
    assert not distortion_from_info(msg)[1].any()


def _info(model: str, d: list[float]) -> object:
    msg = camera_info_msg(K, 640, 480, STAMP)
    msg.distortion_model, msg.d = model, d
    return msg


@pytest.mark.parametrize(("model", "d", "reason"), [
    ("equidistant", [0.1, 0.0, 0.0, 0.0], "'equidistant' is not supported"),
    ("", [0.1, 0.0, 0.0, 0.0, 0.0], "'' is not supported"),
    ("plumb_bob", [0.1, 0.0, 0.0, 0.0], "needs 5 coefficients in d, got 4"),
    ("rational_polynomial", [0.1] * 5, "needs 8 coefficients in d, got 5"),
    ("plumb_bob", [float("nan"), 0.0, 0.0, 0.0, 0.0], "finite"),
    ("plumb_bob", [1e6, 0.0, 0.0, 0.0, 0.0], "finite and within"),
])
def test_each_distortion_refusal_names_its_reason(model: str, d: list[float],
                                                   reason: str) -> None:
    with pytest.raises(ValueError, match=reason.replace("(", r"\(")):
        distortion_from_info(_info(model, d))
