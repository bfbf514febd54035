"""Which estimate starts a graph episode (pushbot.runner.graph_record.first_estimate)."""

from __future__ import annotations

from pushbot.runner.graph_record import first_estimate


def test_an_old_filters_estimate_of_the_new_scene_is_not_the_first() -> None:
    # The CI run that failed: the new scene's first frame is at 29.265 s; perception measured
    # it and the frame at 29.364 s against the old (disc) reference before its reset, so the
    # estimator, reset with its boundary at 29.265 s, gave an estimate at 29.364 s from the old
    # filter; perception's new reference is the frame at 29.464 s.
    old_outlines = [2.732, 19.223]
    estimates = [(27.1, "old episode"), (29.364, "old filter, new scene"),
                 (29.464, "reference"), (29.564, "next")]
    assert first_estimate(old_outlines, estimates, scene=29.265, after=29.265) is None
    assert first_estimate([*old_outlines, 29.464], estimates, 29.265, 29.265) == (
        29.464, 29.464, "reference")


def test_the_reference_may_be_the_scenes_first_frame_and_the_boundary_later() -> None:
    estimates = [(29.265, "reference"), (29.364, "next")]
    assert first_estimate([29.265], estimates, 29.265, after=-1.0) == (29.265, 29.265,
                                                                        "reference")
    # the estimator's boundary is past the reference (its filter took the reference frame
    # before the new outline): the next estimate
    assert first_estimate([29.265], estimates, 29.265, after=29.265) == (29.265, 29.364, "next")
    assert first_estimate([29.265], [], 29.265, after=29.265) is None
