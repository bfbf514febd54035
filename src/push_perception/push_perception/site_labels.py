"""Labels for a site's frames from the depth segmentation, checked across frames.

ROS-free (numpy, OpenCV). ``pushbot data record`` feeds the frames of live camera topics to
:class:`SiteLabeller` one by one; it returns the frames it keeps, each with its label, and
counts every frame it drops by reason. The rule (docs/design/site-adaptation.md, "Labels
from depth, checked across frames"):

1. Each frame is segmented from depth alone
   (:class:`~push_perception.depth_segmentation.DepthSegmenter` with the node's settings). A
   frame whose table-plane fit has an RMS residual above ``max_plane_rms`` is dropped (``plane``).
2. A frame joins the current *run* when its mask agrees with the run's last frame (IoU >=
   ``min_iou``) and the camera (K, extrinsics, image size) is the same (the last frame of the
   scene's previous run, after a label). A disagreeing frame is
   dropped (``disagree``); when the next frame disagrees with the run too but agrees with the
   disagreeing one, the scene has changed: the old run ends (its frames dropped as
   ``short_run`` when fewer than ``window``) and the two start the new run.
3. When a run holds ``window`` frames, the label is the depth segmentation of their per-pixel
   median depth with ``label_min_height`` (the sensor noise averaged out, so a lower height
   threshold keeps the bottom of the object's walls). Each frame of the run is kept with that
   label when its own mask agrees with it (IoU >= ``min_iou``), else dropped (``disagree``);
   an empty label drops the whole run (``empty``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from push_perception.depth_segmentation import DepthSegmentationConfig, DepthSegmenter

__all__ = ["DROP_REASONS", "LabelRule", "LabelledFrame", "SiteLabeller", "mask_iou"]

#: Why a frame is dropped (the keys of :attr:`SiteLabeller.dropped`).
DROP_REASONS = ("plane", "disagree", "short_run", "empty")


def mask_iou(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> float:
    """Intersection over union of two (H, W) bool masks (1 when both are empty)."""
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else float(np.count_nonzero(a & b)) / union


@dataclass(frozen=True)
class LabelRule:
    """Parameters of the consistency rule (module docstring).

    Attributes
    ----------
    min_iou : float
        Agreement of two masks, (0, 1].
    max_plane_rms : float
        Largest RMS residual of the table-plane fit, m.
    window : int
        Frames of a resting scene per label, >= 2.
    label_min_height : float
        ``min_height`` of the depth segmentation on the median depth, m.
    """

    min_iou: float = 0.9
    max_plane_rms: float = 0.002
    window: int = 5
    label_min_height: float = 0.0012

    def __post_init__(self) -> None:
        if not 0.0 < self.min_iou <= 1.0:
            raise ValueError(f"min_iou: must be in (0, 1], got {self.min_iou!r}")
        if not (np.isfinite(self.max_plane_rms) and self.max_plane_rms > 0):
            raise ValueError(f"max_plane_rms: must be > 0 m, got {self.max_plane_rms!r}")
        if isinstance(self.window, bool) or int(self.window) != self.window or self.window < 2:
            raise ValueError(f"window: expected an integer >= 2, got {self.window!r}")
        if not 0.0 < self.label_min_height < DepthSegmentationConfig().max_height:
            raise ValueError(f"label_min_height: must be in (0, max_height) m, got "
                             f"{self.label_min_height!r}")


@dataclass(frozen=True)
class LabelledFrame:
    """A kept frame: its own images with the run's label (``camera_color_optical_frame``).

    Attributes
    ----------
    rgb : (H, W, 3) uint8
    depth : (H, W) float32
        z-depth, m, NaN = no return.
    mask : (H, W) bool
        The label.
    camera_matrix : (3, 3)
    T_world_camera : (4, 4)
    stamp : float
        s.
    scene : int
        Index of the run's scene (counts scene changes from 0).
    """

    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    mask: NDArray[np.bool_]
    camera_matrix: NDArray[np.float64]
    T_world_camera: NDArray[np.float64]  # noqa: N815 - the contract's name
    stamp: float
    scene: int


@dataclass
class _Frame:
    rgb: NDArray[np.uint8]
    depth: NDArray[np.float32]
    k: NDArray[np.float64]
    t: NDArray[np.float64]
    stamp: float
    mask: NDArray[np.bool_]

    def same_camera(self, other: _Frame) -> bool:
        return (self.depth.shape == other.depth.shape and np.array_equal(self.k, other.k)
                and np.array_equal(self.t, other.t))


@dataclass
class SiteLabeller:
    """Streaming labeller of a site's frames (module docstring). Not thread-safe.

    Attributes
    ----------
    rule : LabelRule
    depth : DepthSegmentationConfig
        Settings of the per-frame depth segmentation (the node's by default).
    dropped : dict of str to int
        Frames dropped so far, per reason in :data:`DROP_REASONS`.
    kept : int
        Frames returned with a label so far.
    scene : int
        Index of the current scene.
    """

    rule: LabelRule = field(default_factory=LabelRule)
    depth: DepthSegmentationConfig = field(default_factory=DepthSegmentationConfig)
    dropped: dict[str, int] = field(default_factory=lambda: dict.fromkeys(DROP_REASONS, 0))
    kept: int = 0
    scene: int = 0

    def __post_init__(self) -> None:
        self._frame_seg = DepthSegmenter(self.depth)
        self._label_seg = DepthSegmenter(dataclasses.replace(
            self.depth, min_height=self.rule.label_min_height))
        self._run: list[_Frame] = []
        self._last: _Frame | None = None  # the scene's last frame that joined a run
        self._odd: _Frame | None = None  # the last disagreeing frame

    def add(self, rgb: NDArray[np.uint8], depth: NDArray[np.floating],
            camera_matrix: NDArray[np.floating], t_world_camera: NDArray[np.floating],
            stamp: float) -> list[LabelledFrame]:
        """Offer one frame (the arguments of the segmenters, and its stamp, s).

        Returns
        -------
        list of LabelledFrame
            The frames kept now (empty until a run is complete).
        """
        z = np.asarray(depth, dtype=np.float32)
        k = np.asarray(camera_matrix, dtype=np.float64)
        t = np.asarray(t_world_camera, dtype=np.float64)
        mask = self._frame_seg(rgb, z, k, t).mask
        rms = self._frame_seg.last_plane_rms
        if not (np.isfinite(rms) and rms <= self.rule.max_plane_rms):
            self.dropped["plane"] += 1
            return []
        frame = _Frame(np.asarray(rgb, dtype=np.uint8), z, k, t, float(stamp), mask)
        if self._last is None or self._agrees(frame, self._last):
            if self._odd is not None:  # the odd frame was a glitch of this scene
                self.dropped["disagree"] += 1
            self._run.append(frame)
            self._last, self._odd = frame, None
        elif self._odd is not None and self._agrees(frame, self._odd):
            self._end_run()
            self.scene += 1
            self._run, self._last, self._odd = [self._odd, frame], frame, None
        else:
            if self._odd is not None:  # the previous odd frame stays alone: dropped
                self.dropped["disagree"] += 1
            self._odd = frame
        if self._odd is not None and self._odd is frame:
            return []
        if len(self._run) >= self.rule.window:
            return self._label_run()
        return []

    def finish(self) -> None:
        """End of the stream: an incomplete run and a pending odd frame are dropped (counted)."""
        self._end_run()
        if self._odd is not None:
            self.dropped["disagree"] += 1
            self._odd = None

    def _agrees(self, a: _Frame, b: _Frame) -> bool:
        return a.same_camera(b) and mask_iou(a.mask, b.mask) >= self.rule.min_iou

    def _end_run(self) -> None:
        self.dropped["short_run"] += len(self._run)
        self._run = []

    def _label_run(self) -> list[LabelledFrame]:
        run, self._run = self._run, []
        stack = np.stack([f.depth for f in run])
        # a pixel takes the median of its returns where most frames have one; elsewhere it
        # stays without depth (a hole, not a guess)
        valid = np.isfinite(stack).sum(axis=0) > len(run) // 2
        filled = np.where(np.isfinite(stack), stack, 0.0)
        order = np.sort(np.where(np.isfinite(stack), filled, np.inf), axis=0)
        counts = np.isfinite(stack).sum(axis=0)
        lo = np.take_along_axis(order, ((np.maximum(counts, 1) - 1) // 2)[None], axis=0)[0]
        hi = np.take_along_axis(order, (np.maximum(counts, 1) // 2)[None], axis=0)[0]
        median = np.where(valid, 0.5 * (lo + hi), np.nan).astype(np.float32)
        ref = run[-1]
        label = self._label_seg(ref.rgb, median, ref.k, ref.t).mask
        if not label.any():
            self.dropped["empty"] += len(run)
            return []
        out = []
        for f in run:
            if mask_iou(f.mask, label) >= self.rule.min_iou:
                out.append(LabelledFrame(f.rgb, f.depth, label, f.k, f.t, f.stamp, self.scene))
            else:
                self.dropped["disagree"] += 1
        self.kept += len(out)
        return out
