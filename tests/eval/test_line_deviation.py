"""The arm's contact-line error of graph records (pushbot.runner.graph_record.line_deviation)."""

from __future__ import annotations

import numpy as np
import pytest

from pushbot.runner.graph_record import line_deviation


def test_distance_from_the_segment_by_hand() -> None:
    contact, end = np.array([0.0, 0.0]), np.array([0.04, 0.0])
    tip = np.array([[0.01, 0.0003, 0.01],    # on the segment, 0.3 mm off
                    [0.03, -0.0008, 0.01],   # 0.8 mm off: the largest in contact
                    [0.05, 0.0050, 0.01],    # past the end: not on the segment
                    [-0.01, 0.0040, 0.01],   # before the contact point (approach)
                    [0.02, 0.0500, 0.10]])   # transit above the segment: too high
    assert line_deviation(tip, contact, end) == pytest.approx(0.0008)


def test_a_rotated_segment_and_no_sample_in_contact() -> None:
    contact, end = np.array([0.1, 0.1]), np.array([0.1 + 0.03, 0.1 + 0.04])  # length 5 cm
    normal = np.array([-0.8, 0.6])
    tip = np.array([[*(contact + 0.6 * (end - contact) + 0.002 * normal), 0.01]])
    assert line_deviation(tip, contact, end) == pytest.approx(0.002)
    assert line_deviation(tip + [0.0, 0.0, 0.05], contact, end) is None
    assert line_deviation(tip, contact, contact) is None
