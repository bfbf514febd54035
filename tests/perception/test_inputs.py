"""push_perception.inputs: the node's input rules without rclpy (pairing, consistency,
re-anchoring), against hand-worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from push_perception.inputs import (
    MIN_VALID_DEPTH,
    REFUSAL_KINDS,
    AnchorWait,
    FrameSync,
    InputError,
    check_depth_coverage,
    check_frame_ids,
    check_frame_inputs,
    check_stamp,
    rgb_from_color,
)
from push_perception.perception_config import PerceptionError


def test_input_error_is_a_perception_error_of_a_known_kind() -> None:
    exc = InputError("stamp", "bad")
    assert isinstance(exc, PerceptionError) and isinstance(exc, ValueError)
    assert exc.kind == "stamp" and str(exc) == "bad"
    with pytest.raises(ValueError, match="unknown refusal kind 'empty_mask'"):
        InputError("empty_mask", "an outcome, not a refusal")
    assert len(set(REFUSAL_KINDS)) == len(REFUSAL_KINDS)


@pytest.mark.parametrize(("sec", "nanosec"), [(-1, 0), (0, 1_000_000_000), (-(2**31), 5),
                                              (3, 2**32 - 1)])
def test_check_stamp_refuses_times_outside_the_range(sec: int, nanosec: int) -> None:
    with pytest.raises(InputError, match=r"is not a time in \[0, 2\^31\) s") as info:
        check_stamp(sec, nanosec)
    assert info.value.kind == "stamp"


def test_check_stamp_returns_the_key() -> None:
    assert check_stamp(0, 0) == (0, 0)
    assert check_stamp(2**31 - 1, 999_999_999) == (2**31 - 1, 999_999_999)


def test_frame_sync_pairs_by_identical_stamps_in_any_order() -> None:
    sync = FrameSync(5)
    assert sync.add("info", (1, 0), "i1") == (None, [])
    assert sync.add("depth", (1, 0), "d1") == (None, [])
    assert sync.snapshot() == (((1, 0), ("depth", "info")),)
    frame, missing = sync.add("rgb", (1, 0), "c1")
    assert frame == ("c1", "d1", "i1") and missing == []  # always (rgb, depth, info)
    assert sync.snapshot() == ()  # a complete frame leaves the queue
    # 1 ns apart is another frame.
    assert sync.add("rgb", (2, 0), "c2") == (None, [])
    assert sync.add("depth", (2, 1), "d2") == (None, [])
    assert [key for key, _ in sync.snapshot()] == [(2, 0), (2, 1)]


def test_frame_sync_drops_what_arrived_before_a_complete_frame() -> None:
    sync = FrameSync(5)
    sync.add("rgb", (1, 0), "c1")
    sync.add("depth", (1, 0), "d1")  # a pair without camera_info: reported when dropped
    sync.add("rgb", (2, 0), "c2")  # a lone colour image: dropped silently
    sync.add("rgb", (3, 0), "c3")
    sync.add("depth", (3, 0), "d3")
    sync.add("rgb", (4, 0), "c4")  # arrives after frame 3: kept
    frame, missing = sync.add("info", (3, 0), "i3")
    assert frame == ("c3", "d3", "i3") and missing == [(1, 0)]
    assert sync.snapshot() == (((4, 0), ("rgb",)),)


def test_frame_sync_keeps_at_most_queue_incomplete_stamps() -> None:
    sync = FrameSync(2)
    sync.add("rgb", (1, 0), "c1")
    sync.add("depth", (1, 0), "d1")
    sync.add("rgb", (2, 0), "c2")
    frame, missing = sync.add("rgb", (3, 0), "c3")  # third stamp: the oldest goes
    assert frame is None and missing == [(1, 0)]
    frame, missing = sync.add("depth", (4, 0), "d4")
    assert frame is None and missing == []  # (2, 0) was a lone colour image
    assert [key for key, _ in sync.snapshot()] == [(3, 0), (4, 0)]
    sync.clear()
    assert sync.snapshot() == ()


@pytest.mark.parametrize("queue", [0, -1, 1.5, True])
def test_frame_sync_checks_its_queue(queue: object) -> None:
    with pytest.raises(ValueError, match="queue must be an integer >= 1"):
        FrameSync(queue)  # type: ignore[arg-type]


def test_frame_sync_refuses_an_unknown_stream() -> None:
    with pytest.raises(ValueError, match="stream must be one of"):
        FrameSync(3).add("ir", (1, 0), "x")


def test_rgb_from_color_swaps_bgr_and_refuses_other_encodings() -> None:
    pixels = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    assert rgb_from_color(pixels, "rgb8") is pixels
    swapped = rgb_from_color(pixels, "bgr8")
    np.testing.assert_array_equal(swapped[..., 0], pixels[..., 2])
    np.testing.assert_array_equal(swapped[..., 2], pixels[..., 0])
    assert swapped.flags.c_contiguous
    with pytest.raises(InputError, match="encoding 'rgba8'; expected rgb8 or bgr8"):
        rgb_from_color(pixels, "rgba8")
    with pytest.raises(InputError, match=r"shape \(2, 3\); expected \(H, W, 3\)"):
        rgb_from_color(pixels[..., 0], "rgb8")


def test_check_depth_coverage_at_the_threshold() -> None:
    depth = np.full((10, 10), np.nan, dtype=np.float32)
    depth.flat[:5] = 1.0  # 5 % valid: exactly MIN_VALID_DEPTH
    assert MIN_VALID_DEPTH == 0.05
    assert check_depth_coverage(depth) == pytest.approx(0.05)
    depth.flat[4] = np.inf
    with pytest.raises(PerceptionError, match=r"only 4\.0 % of the depth image is valid") as info:
        check_depth_coverage(depth)
    assert info.value.kind == "no_depth" and not isinstance(info.value, InputError)
    with pytest.raises(PerceptionError, match=r"only 0\.0 %"):
        check_depth_coverage(np.zeros((0, 4), dtype=np.float32))


def test_check_frame_inputs_sizes() -> None:
    check_frame_inputs((640, 480), (640, 480), (640, 480))
    with pytest.raises(InputError, match="colour is 640x480 but depth is 320x240") as info:
        check_frame_inputs((640, 480), (320, 240), (640, 480))
    assert info.value.kind == "size_mismatch"
    with pytest.raises(InputError, match="camera_info is for 320x480 images, the images are "
                                         "640x480") as info:
        check_frame_inputs((640, 480), (640, 480), (320, 480))
    assert info.value.kind == "camera_info"


def test_check_frame_ids() -> None:
    check_frame_ids("cam", "cam", "cam")
    check_frame_ids("cam", "cam", "")  # no child frame to compare (tf2 lookup)
    for depth_frame, child in (("other", "cam"), ("cam", "other")):
        with pytest.raises(InputError, match="must be the same frame") as info:
            check_frame_ids("cam", depth_frame, child)
        assert info.value.kind == "frame_mismatch"
    with pytest.raises(InputError) as info:  # a 1 MB frame id is quoted short
        check_frame_ids("x" * 10**6, "cam", "")
    assert len(str(info.value)) < 300


OUTLINE = np.array([[0.01, 0.0], [0.0, 0.01], [-0.01, 0.0]])


def test_anchor_wait_anchors_with_an_outline_and_a_later_estimate() -> None:
    wait = AnchorWait(5.0, now=100.0)
    assert wait.waiting
    assert wait.admit(1.0, False, now=101.0) == "wait"  # nothing latched yet
    wait.offer_outline(OUTLINE, OUTLINE, stamp=10.0, payload="msg")
    wait.offer_estimate(9.5, 0.3)  # older than the outline: not this episode's estimate
    assert wait.admit(2.0, False, now=102.0) == "wait"
    wait.offer_estimate(10.0, 0.3)
    assert wait.admit(3.0, False, now=103.0) == "anchor"
    assert wait.outline.payload == "msg" and wait.estimate == (10.0, 0.3)
    assert not wait.waiting and wait.admit(4.0, True, now=103.5) == "go"
    assert wait.last_frame == 4.0  # waiting frames were not processed frames


def test_anchor_wait_gives_up_after_the_timeout_or_with_a_reference() -> None:
    wait = AnchorWait(5.0, now=100.0)
    assert wait.decide(False, now=104.999) == "wait"
    assert wait.decide(False, now=105.0) == "go" and not wait.waiting
    wait = AnchorWait(5.0, now=100.0)
    assert wait.decide(True, now=100.0) == "go" and not wait.waiting
    never = AnchorWait(0.0, now=100.0)
    assert not never.waiting and never.decide(False, now=100.0) == "go"
    with pytest.raises(ValueError, match="timeout must be a finite number >= 0 s"):
        AnchorWait(-1.0, now=0.0)
    with pytest.raises(ValueError, match="must be finite"):
        never.offer_estimate(1.0, math.nan)


def test_anchor_wait_reset_marks_the_previous_episode() -> None:
    wait = AnchorWait(5.0, now=0.0)
    wait.offer_outline(OUTLINE, OUTLINE, stamp=1.0)
    assert wait.admit(7.0, True, now=1.0) == "go"
    wait.reset()  # ends the wait too: an explicit new episode
    assert not wait.waiting
    assert wait.admit(7.0, False, now=2.0) == "previous"  # the old scene, re-published
    assert wait.admit(7.0, False, now=2.0) == "previous"
    assert wait.admit(8.0, False, now=2.0) == "go"
    assert wait.admit(1.0, False, now=2.0) == "go"  # a restarted clock is not the old scene
    wait.reset(boundary=20.0)  # a reset at sim time 20 s (after the newest frame, 8 s)
    assert wait.admit(19.5, False, now=3.0) == "previous"  # taken before the reset
    assert wait.admit(20.0, False, now=3.0) == "previous"
    assert wait.admit(20.5, False, now=3.0) == "go"  # the camera's next frame
