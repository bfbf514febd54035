"""pushbot eval perception: symmetry detection and a small end-to-end run with its report."""

from __future__ import annotations

import argparse

import pytest

from push_core.objects import load_object
from pushbot.experiments.perception_evaluation import (
    EvalConfig,
    add_arguments,
    evaluate,
    format_report,
    summary,
    symmetry_order,
)


@pytest.mark.parametrize(("obj", "order"), [("tri1", 1), ("butter", 2), ("hex", 6),
                                            ("rect1", 4), ("rect3", 2)])
def test_symmetry_order_of_library_objects(obj: str, order: int) -> None:
    assert symmetry_order(load_object(obj).polyline()) == order


def test_small_evaluation_reports_every_metric() -> None:
    cfg = EvalConfig(objects=("hex",), episodes=2, frames=2, seed=3)
    rows = evaluate(cfg, progress=False)
    assert len(rows.frame) == 4 and len(rows.outline) == 2
    assert [r["randomised"] for r in rows.frame] == [False, False, True, True]
    assert all(not r["failure"] for r in rows.frame)
    s = summary(rows)["all"]
    assert s["iou"] > 0.95 and s["position_mm"] < 3.0 and s["orientation_deg"] < 2.0
    report = format_report(rows, cfg)
    assert "| hex | 4 (4) |" in report and "| latency_ms |" in report
    assert "Frames without a pose: none" in report


def test_command_line_defaults_are_the_documented_protocol() -> None:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    args = parser.parse_args([])
    assert (tuple(args.objects), args.episodes, args.frames, args.seed) == (
        ("tri1", "butter", "hex"), 10, 10, 0)
