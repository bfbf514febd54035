"""pushbot eval push (pushbot.experiments.evaluate): options, determinism, outputs, error
messages."""

from __future__ import annotations

import importlib.util
import json
import math
import sys

import pytest

from pushbot import cli
from pushbot.experiments.eval_report import (
    deterministic_view,
    stats,
    summarise,
    table_5_1,
    table_5_2,
    write_outputs,
)
from pushbot.experiments.evaluate import EvalOptions, build_trials, evaluate

SMALL = dict(objects=["rect1"], tasks=["mixed", "rotation"], methods=["ana", "pushnet"],
             k=[1], trials=2, seed=5)


def _record(success, steps, xy, theta, **trial):
    base = dict(object="butter", task="mixed", method="ana", k=3, state="gt", com="centre",
                region="small", index=0, seed=0, max_steps=30, estimate_com=True)
    base.update(trial)
    return {"trial": base, "success": success, "steps": steps, "end_error_xy": xy,
            "end_error_theta": theta, "com_error": None, "planning_ms": [1.0, 3.0],
            "wall_s": 0.5, "reason": "goal reached" if success else "max steps"}


def test_stats_by_hand():
    recs = [_record(True, 4, 0.002, 0.01), _record(True, 6, 0.004, 0.03),
            _record(False, 30, 0.05, 0.2)]
    s = stats(recs)
    assert s["n"] == 3 and s["successes"] == 2
    assert s["success_rate"] == pytest.approx(2 / 3)
    assert s["steps_mean"] == pytest.approx(5.0) and s["steps_std"] == pytest.approx(1.0)
    assert s["end_error_xy_mean"] == pytest.approx((0.002 + 0.004 + 0.05) / 3)
    assert s["com_error_mean"] is None
    assert s["reasons"] == {"goal reached": 2, "max steps": 1}
    assert s["timing"]["planning_ms_median"] == pytest.approx(2.0)


def test_summarise_groups_cells_and_tables_use_the_source_numbers():
    recs = [_record(True, 4, 0.002, 0.01, index=0), _record(True, 6, 0.004, 0.03, index=1),
            _record(True, 5, 0.006, 0.02, state="filter", index=0)]
    cells = summarise(recs)
    assert [c["state"] for c in cells] == ["gt", "filter"]
    assert [c["n"] for c in cells] == [2, 1]
    t = table_5_1(recs)
    assert "7.3 +- 3.6" in t and "8.7 +- 4.2" in t  # the source's rows
    assert "| 2 | 1.000 | 5.0 +- 1.0 | 3.0 +- 1.0 |" in t  # ours (gt)
    assert table_5_2(recs) is None  # no random-COM filter trials
    recs52 = [_record(True, 9, 0.003, 0.02, com="random", state="filter", method="lrn",
                      estimate_com=False, object="hex")]
    t52 = table_5_2(recs52)
    assert "| lrn | 1.00 / 9.0 (source 0.92 / 13.2) |" in t52


def test_build_trials_cross_product_and_deduplication():
    opts = EvalOptions(objects=["rect1"], tasks=["mixed"], methods=["ana", "pushnet"],
                       k=[1, 3], state=["gt", "filter"], com_estimation=["off", "on"],
                       trials=2)
    trials = build_trials(opts)
    cells = {(t.method, t.k, t.state, t.estimate_com) for t in trials}
    # ana: 2 k x (gt on) + 2 k x filter (off, on) = 6; pushnet: first k only -> 1 + 2 = 3
    assert len(cells) == 9
    assert ("pushnet", 3, "gt", True) not in cells
    assert ("ana", 1, "gt", False) not in cells
    assert len(trials) == 2 * len(cells)
    assert [t.index for t in trials[:2]] == [0, 1]


def test_planner_and_filter_variants_reach_every_layer_and_keep_the_scenes():
    """--horizon / --avoid-contradicted / --relearn: carried by every trial into
    the in-process planner and filter and the graph's node parameters; the variant is part of
    the cell, not of the trial's seed (the same scenes, goals and planner seeds)."""
    from push_planner.config import PARAMETERS as PLANNER_PARAMETERS
    from pushbot.experiments.inprocess import EpisodeRunner
    from pushbot.runner.protocol import Trial, planner_episode_params

    base = build_trials(EvalOptions(objects=["rect1"], tasks=["mixed"], trials=2))
    opts = EvalOptions(objects=["rect1"], tasks=["mixed"], trials=2, horizon=3,
                       avoid_contradicted=True, relearn=True)
    trials = build_trials(opts)
    assert opts.as_dict()["horizon"] == 3 and opts.as_dict()["relearn"] is True
    assert [(t.horizon, t.avoid_contradicted, t.relearn) for t in trials] == [(3, True, True)] * 2
    assert [t.trial_seed for t in trials] == [t.trial_seed for t in base]
    assert [t.planner_seed for t in trials] == [t.planner_seed for t in base]
    assert [(b.horizon, b.avoid_contradicted, b.relearn) for b in base] == [(1, False, False)] * 2
    kw = trials[0].planner_kwargs()
    assert kw["horizon"] == 3 and kw["avoid_contradicted"] is True
    params = planner_episode_params(trials[0])
    assert params["lookahead.horizon"] == 3 and params["avoid_contradicted"] is True
    assert set(params) <= {spec.name for spec in PLANNER_PARAMETERS}
    runner = EpisodeRunner()
    assert runner._ekf_config(trials[0]).relearn is True
    assert runner._ekf_config(base[0]).relearn is False
    assert runner._ekf_config(Trial(object="rect1", state="filter", relearn=True,
                                    estimate_com=False)).relearn is True
    recs = [_record(True, 4, 0.002, 0.01, **t.as_dict()) for t in base + trials]
    assert [c["horizon"] for c in summarise(recs)] == [1, 3]
    for bad, match in (({"horizon": 0}, "horizon must be an integer >= 1"),
                       ({"horizon": 1.5}, "horizon"), ({"relearn": "yes"}, "relearn must be"),
                       ({"avoid_contradicted": 1}, "avoid_contradicted must be")):
        with pytest.raises(ValueError, match=match):
            Trial(object="rect1", **bad)


def test_the_support_cell_is_a_world_variant_of_the_same_scenes():
    from pushbot.experiments.eval_report import variant_label
    from pushbot.runner.protocol import Trial

    base = build_trials(EvalOptions(objects=["rect1"], tasks=["mixed"], trials=2))
    cut = build_trials(EvalOptions(objects=["rect1"], tasks=["mixed"], trials=2,
                                   support_cell=0.015))
    assert [t.support_cell for t in cut] == [0.015] * 2 and base[0].support_cell == 0.0
    assert [t.trial_seed for t in cut] == [t.trial_seed for t in base]
    assert cut[0].world_kwargs()["support_cell"] == 0.015
    assert base[0].world_kwargs()["support_cell"] == 0.0
    assert variant_label(cut[0].as_dict()) == "greedy, support 15 mm"
    assert variant_label(base[0].as_dict()) == "greedy"
    recs = [_record(True, 4, 0.002, 0.01, **t.as_dict()) for t in base + cut]
    assert [c["support_cell"] for c in summarise(recs)] == [0.0, 0.015]
    for bad in (0.001, 0.06, -0.01, True, "1 cm"):
        with pytest.raises(ValueError, match="support_cell must be 0 or in"):
            Trial(object="rect1", support_cell=bad)
    with pytest.raises(ValueError, match="--support-cell"):
        EvalOptions(objects=["rect1"], support_cell=0.2)


def test_cli_takes_the_variant_flags():
    import argparse

    from pushbot.experiments.evaluate import add_arguments, options_from_args

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    opts = options_from_args(parser.parse_args(["--objects", "rect1", "--horizon", "2",
                                                "--avoid-contradicted", "--relearn"]))
    assert (opts.horizon, opts.avoid_contradicted, opts.relearn) == (2, True, True)
    opts = options_from_args(parser.parse_args(["--objects", "rect1"]))
    assert (opts.horizon, opts.avoid_contradicted, opts.relearn) == (1, False, False)
    assert opts.support_cell == 0.0
    opts = options_from_args(parser.parse_args(["--objects", "rect1", "--support-cell", "0.01"]))
    assert opts.support_cell == 0.01


@pytest.mark.parametrize("kwargs, match", [
    ({"tasks": ["push"]}, "--tasks: unknown value"),
    ({"methods": ["best"]}, "--methods: unknown value.*best"),
    ({"k": [0]}, "--k"),
    ({"state": ["sensor"]}, "--state"),
    ({"region": ["huge"]}, "--region"),
    ({"com_estimation": ["maybe"]}, "--com-estimation"),
    ({"trials": 0}, "--trials"),
    ({"objects": ["no_such_object"]}, "--objects: 'no_such_object'"),
    ({"objects": []}, "--objects: give at least one"),
    ({"horizon": 0}, "--horizon"),
])
def test_option_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        EvalOptions(**kwargs)


def test_bad_object_spec_file_is_a_clear_error(tmp_path, capsys):
    spec = tmp_path / "broken.yaml"
    spec.write_text("name: broken\nshape:\n  type: polygon\n  vertices: [[0, 0], [1, 0]]\n"
                    "thickness: 0.01\nmass: 0.1\n")
    code = cli.main(["eval", "push", "--objects", str(spec), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "--objects" in err and "broken.yaml" in err and "Traceback" not in err


def test_cli_bad_task_exit_code(tmp_path, capsys):
    assert cli.main(["eval", "push", "--tasks", "fly", "--out", str(tmp_path)]) == 2
    assert "--tasks: unknown value(s) fly" in capsys.readouterr().err


def test_same_seed_same_json_in_process_and_with_workers(tmp_path):
    opts = EvalOptions(**SMALL)
    a = evaluate(opts, workers=1, progress=False)
    b = evaluate(opts, workers=2, progress=False)
    assert deterministic_view(a) == deterministic_view(b)
    assert "timing" in a and "timing" not in deterministic_view(a)
    # a different seed gives other scenes
    c = evaluate(EvalOptions(**{**SMALL, "seed": 6}), workers=1, progress=False)
    assert deterministic_view(c)["trials"] != deterministic_view(a)["trials"]
    # the written JSON holds the same
    written = write_outputs(a, tmp_path)
    doc = json.loads((tmp_path / "results.json").read_text())
    assert deterministic_view(doc) == json.loads(json.dumps(deterministic_view(a)))
    assert {p.name for p in written} >= {"results.json", "fig5_7.png"}
    assert len(doc["cells"]) == 4 and all(c["n"] == 2 for c in doc["cells"])
    assert doc["cells"][0]["success_rate"] == 1.0  # rect1, ana, gt


def test_cli_writes_outputs(tmp_path, capsys):
    out = tmp_path / "eval"
    code = cli.main(["eval", "push", "--objects", "rect1", "--tasks", "mixed", "--trials", "2",
                     "--methods", "ana", "--k", "1", "3", "--workers", "1", "--no-progress",
                     "--out", str(out)])
    assert code == 0
    printed = capsys.readouterr().out
    assert "| rect1 | mixed | ana | 1 | gt |" in printed
    doc = json.loads((out / "results.json").read_text())
    assert [c["k"] for c in doc["cells"]] == [1, 3]
    assert (out / "fig5_5.png").stat().st_size > 1000
    assert "Table 5.1" in (out / "tables.md").read_text()
    s = doc["cells"][0]
    assert 0.0 <= s["end_error_theta_mean"] <= math.radians(5)


def test_graph_flag_without_graph_module_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pushbot.runner.episode", None)  # import fails
    code = cli.main(["eval", "push", "--graph", "--objects", "rect1", "--trials", "1",
                     "--tasks", "mixed", "--out", str(tmp_path)])
    assert code == 2
    assert "--graph needs pushbot.runner.episode" in capsys.readouterr().err


def test_graph_flag_hands_the_trials_to_the_graph_runner(tmp_path, monkeypatch):
    import types

    seen = {}

    def fake(trials, *, out_dir, progress, robot):
        seen["trials"], seen["out_dir"], seen["robot"] = list(trials), out_dir, robot
        return [_record(True, 3, 0.002, 0.01, **t.as_dict()) for t in trials]

    monkeypatch.setitem(sys.modules, "pushbot.runner.episode",
                        types.SimpleNamespace(run_graph_trials=fake))
    opts = EvalOptions(objects=["rect1"], tasks=["mixed"], trials=3)
    doc = evaluate(opts, graph=True, out_dir=tmp_path, progress=False)
    assert [t.index for t in seen["trials"]] == [0, 1, 2] and seen["robot"] == "pusher"
    assert doc["cells"][0]["n"] == 3 and doc["timing"]["engine"] == "graph"
    doc = evaluate(opts, graph=True, out_dir=tmp_path, progress=False, robot="arm")
    assert seen["robot"] == "arm" and doc["timing"]["engine"] == "graph (arm)"


def test_ray_missing_is_a_clear_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` fails as if not installed
    code = cli.main(["eval", "push", "--ray", "local", "--objects", "rect1", "--trials", "1",
                     "--out", str(tmp_path)])
    assert code == 2
    assert "pip install 'pushbot[ray]'" in capsys.readouterr().err


@pytest.mark.skipif(importlib.util.find_spec("ray") is None, reason="ray is not installed")
def test_ray_local_runs_the_same_trials():
    opts = EvalOptions(objects=["rect1"], tasks=["mixed"], trials=2, k=[1])
    a = evaluate(opts, workers=1, progress=False)
    import ray

    try:
        b = evaluate(opts, ray_address="local", progress=False)
    finally:
        ray.shutdown()  # no raylet left running for the rest of the session
    assert b["timing"]["engine"] == "ray (local)"
    assert deterministic_view(a) == deterministic_view(b)
