"""push_core.calibration.charuco: the printed board image is detected at its corners."""

from __future__ import annotations

import cv2
import numpy as np

from push_core.calibration.charuco import BoardSpec, detect_board

BOARD = BoardSpec()


def test_the_board_image_is_detected_at_its_printed_corners() -> None:
    px = 40
    image = BOARD.image(px)
    page = np.full((image.shape[0] + 80, image.shape[1] + 80), 255, np.uint8)
    page[40:-40, 40:-40] = image
    # A camera's optics blur a little; the saddle refinement of a perfectly sharp step is
    # biased by a fraction of a pixel.
    page = cv2.GaussianBlur(page, (0, 0), 1.0)
    ids, pixels = detect_board(BOARD, page)
    assert ids.tolist() == list(range(len(BOARD.corners)))
    # A corner at board (x, y) is at pixel x / s - 0.5 + margin (pixel centres).
    expected = BOARD.corners[:, :2] * px / BOARD.square - 0.5 + 40
    np.testing.assert_allclose(pixels, expected, atol=0.1)
    none_ids, none_px = detect_board(BOARD, np.full((100, 100, 3), 128, np.uint8))
    assert none_ids.size == 0 and none_px.shape == (0, 2)
