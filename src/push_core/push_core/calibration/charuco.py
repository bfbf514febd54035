"""The calibration target: a ChArUco board (``cv2.aruco``), its corners, image and detection.

A ChArUco board is a chessboard whose white squares hold ArUco markers. The chessboard
corners are what is measured (saddle points, refined to a fraction of a pixel and unbiased by
blur or exposure, unlike a marker's edges); the markers only name them, so a board partly
hidden by the arm or leaving the image still gives correctly numbered corners.

Board frame (OpenCV's): origin at the board's outer corner by the first row and column of
squares, x along the rows of the printed image (to the right), y down the printed image,
z = x cross y into the board (away from a viewer of the printed face); every corner lies on
z = 0. A camera sees the printed face when its optical z axis points along the board's +z.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["BoardSpec", "detect_board"]


@dataclass(frozen=True)
class BoardSpec:
    """Geometry of the ChArUco board.

    Attributes
    ----------
    squares_x, squares_y : int
        Squares along the board's x and y axes (the inner corners are
        ``(squares_x - 1) x (squares_y - 1)``).
    square : float
        Side of a chessboard square, metres.
    marker : float
        Side of an ArUco marker inside a white square, metres (< ``square``).
    dictionary : str
        Name of the ``cv2.aruco`` predefined dictionary (``DICT_4X4_50``: the fewest bits
        per marker, so the largest cells, the best detected at a small image size).
    """

    squares_x: int = 5
    squares_y: int = 5
    square: float = 0.03
    marker: float = 0.022
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.squares_x < 3 or self.squares_y < 3:
            raise ValueError("board: need at least 3 x 3 squares")
        if not 0 < self.marker < self.square:
            raise ValueError(f"board: need 0 < marker ({self.marker}) < square ({self.square})")
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"board: unknown cv2.aruco dictionary {self.dictionary!r}")

    @cached_property
    def board(self) -> cv2.aruco.CharucoBoard:
        """The ``cv2.aruco.CharucoBoard`` object."""
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square,
                                      self.marker, d)

    @property
    def size(self) -> tuple[float, float]:
        """Board extent ``(x, y)``, metres."""
        return self.squares_x * self.square, self.squares_y * self.square

    @cached_property
    def corners(self) -> NDArray[np.float64]:
        """Inner corners in the board frame, (M, 3) metres; row ``i`` is corner id ``i``."""
        return np.asarray(self.board.getChessboardCorners(), dtype=np.float64).reshape(-1, 3)

    def image(self, px_per_square: int = 64) -> NDArray[np.uint8]:
        """The printed face, (H, W) uint8 grey, no margin: pixel ``(v, u)`` covers board
        ``x in [u, u + 1) s``, ``y in [v, v + 1) s`` with ``s = square / px_per_square``."""
        w, h = self.squares_x * px_per_square, self.squares_y * px_per_square
        return self.board.generateImage((w, h), marginSize=0, borderBits=1)


def detect_board(spec: BoardSpec, image: ArrayLike, min_corners: int = 4
                 ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """ChArUco corners in a camera image.

    Parameters
    ----------
    spec : BoardSpec
        The board looked for.
    image : (H, W) or (H, W, 3) uint8 array
        Grey or RGB image (as the image is, distorted if the lens is).
    min_corners : int
        Fewer corners than this count as not seen.

    Returns
    -------
    ids : (N,) int64
        Corner ids (rows of :attr:`BoardSpec.corners`), ascending; empty when not seen.
    pixels : (N, 2) float64
        Their subpixel image coordinates ``(u, v)``, px.
    """
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(np.ascontiguousarray(img[..., :3]), cv2.COLOR_RGB2GRAY)
    if img.dtype != np.uint8 or img.ndim != 2:
        raise ValueError(f"detect_board: expected a uint8 grey or RGB image, got {img.dtype} "
                         f"{img.shape}")
    corners, ids, _, _ = cv2.aruco.CharucoDetector(spec.board).detectBoard(img)
    if ids is None or len(ids) < min_corners:
        return np.zeros(0, np.int64), np.zeros((0, 2))
    ids = np.asarray(ids, dtype=np.int64).ravel()
    order = np.argsort(ids)
    pixels = np.asarray(corners, dtype=np.float32).reshape(-1, 2)[order]
    return ids[order], _refine_corners(spec, img, pixels).astype(np.float64)


def _refine_corners(spec: BoardSpec, img: NDArray[np.uint8], pixels: NDArray[np.float32]
                    ) -> NDArray[np.float32]:
    """Saddle refinement in a window that stays inside the white margin around each corner.

    The detector's own refinement window reaches the markers next to a corner when the board
    is small in the image, and their edges pull the saddle point by a few tenths of a pixel;
    the window here is 80 % of that margin (from the board's spacing seen in the image).
    """
    if len(pixels) < 2:
        return pixels
    gaps = np.linalg.norm(pixels[:, None] - pixels[None], axis=-1)
    np.fill_diagonal(gaps, np.inf)
    spacing = float(np.median(gaps.min(axis=1)))
    margin = spacing * (spec.square - spec.marker) / (2.0 * spec.square)
    half = int(np.clip(np.floor(0.8 * margin), 2, 5))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    return cv2.cornerSubPix(img, pixels.reshape(-1, 1, 2).copy(), (half, half), (-1, -1),
                            criteria).reshape(-1, 2)
