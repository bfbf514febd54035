"""``pushbot data|train|eval`` as a user runs them: bad input is one line and exit 2 before any
work, small data sets train, training writes under ``out/train/`` unless ``--install`` is
given, and every option's default is shown in ``--help``.

The commands run in-process through :func:`pushbot.cli.main` in a temporary working directory;
data sets are generated for real (pybullet), with the fewest frames and contact points that
exercise the code.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from pathlib import Path

import pytest

from pushbot import cli
from pushbot.experiments import affordance_data, affordance_training, perception_training


def _one_line_exit_2(argv: list[str], capsys: pytest.CaptureFixture[str], message: str) -> str:
    try:
        status = cli.main(argv)
    except SystemExit as exc:  # argparse's errors end the parse
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture
def in_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture(scope="module")
def affordance_set(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three object samples of two contact points in two shards (2 + 1)."""
    out = tmp_path_factory.mktemp("affordances") / "set"
    affordance_data.generate(affordance_data.DataConfig(n_samples=3, shard_size=2,
                                                        points_per_sample=2), out,
                             progress=False)
    return out


# --- bad input, one family at a time -----------------------------------------------------------

def test_train_segmentation_on_one_shard_names_the_minimum(in_tmp: Path, capsys) -> None:
    (in_tmp / "one").mkdir()
    (in_tmp / "one" / "shard_00000.npz").write_bytes(b"")
    _one_line_exit_2(["train", "segmentation", "--data", "one"], capsys,
                     "pushbot train segmentation: one: 1 shard(s); training needs at least 2")
    _one_line_exit_2(["train", "segmentation", "--data", "missing"], capsys,
                     "no shard_*.npz files")
    _one_line_exit_2(["train", "segmentation", "--data", "one", "--steps", "0"], capsys,
                     "--steps 0: expected an integer >= 1")
    _one_line_exit_2(["train", "segmentation", "--install", "--out", "x.pt"], capsys,
                     "argument --out: not allowed with argument --install")
    assert not (in_tmp / "out").exists()


def test_train_affordances_refuses_before_training(in_tmp: Path, affordance_set: Path,
                                                   capsys) -> None:
    _one_line_exit_2(["train", "affordances", "--data", str(affordance_set), "--install"],
                     capsys, "pushbot train affordances: --install needs --test-data")
    _one_line_exit_2(["train", "affordances", "--data", "nowhere"], capsys,
                     "--data nowhere: not a data set of `pushbot data affordances`")
    _one_line_exit_2(["train", "affordances", "--data", str(affordance_set), "--lr", "nan"],
                     capsys, "--lr nan: expected a positive number")
    assert not (in_tmp / "out").exists()


def test_data_perception_refuses_a_folder_of_another_configuration(in_tmp: Path,
                                                                   capsys) -> None:
    (in_tmp / "set").mkdir()
    meta = {"format_version": 1, "config": {"n": 7}}
    (in_tmp / "set" / "meta.json").write_text(json.dumps(meta))
    _one_line_exit_2(["data", "perception", "--n", "4", "--out", "set", "--no-progress"], capsys,
                     "pushbot data perception: set holds a data set with another configuration")
    assert json.loads((in_tmp / "set" / "meta.json").read_text()) == meta
    assert not list((in_tmp / "set").glob("shard_*"))
    _one_line_exit_2(["data", "perception", "--n", "1", "--out", "small"], capsys,
                     "--n 1: need at least 2 frames")
    _one_line_exit_2(["data", "perception", "--n", "4", "--out", "bad", "--width", "3"],
                     capsys, "width: expected an integer >= 8")


def test_data_affordances_refuses_too_small_sets_and_bad_sizes(in_tmp: Path, capsys) -> None:
    _one_line_exit_2(["data", "affordances", "--n", "1", "--out", "a"], capsys,
                     "--n 1: a training set needs at least 2 samples")
    _one_line_exit_2(["data", "affordances", "--n", "4", "--shard-size", "0", "--out", "a"],
                     capsys, "shard_size: expected an integer >= 1")
    assert not (in_tmp / "a").exists()


@pytest.mark.parametrize("argv, message", [
    (["eval", "pusht", "--episodes", "0"], "pushbot eval pusht: episodes, max-steps"),
    (["eval", "estimator", "--episodes", "0"], "pushbot eval estimator: --episodes"),
    (["eval", "push", "--trials", "0"], "--trials: must be an integer >= 1"),
    (["eval", "perception", "--no-such-option"], "unrecognized arguments: --no-such-option"),
])
def test_eval_bad_input_is_one_line(argv: list[str], message: str, capsys) -> None:
    _one_line_exit_2(argv, capsys, message)


# --- small data sets work, and training writes to out/train/ -------------------------------

def test_data_affordances_makes_exactly_n_samples(in_tmp: Path) -> None:
    cfg = affordance_data.DataConfig(n_samples=3, shard_size=2, points_per_sample=1)
    assert cfg.n_shards == 2 and [cfg.shard_length(k) for k in range(2)] == [2, 1]
    shard = affordance_data.generate_shard(cfg, 1, in_tmp)
    assert shard["motion"].shape[:2] == (1, 1)


def test_small_perception_set_trains_into_out_not_the_package(in_tmp: Path, capsys) -> None:
    bundled = perception_training.installed_weights()
    before = _digest(bundled)
    assert cli.main(["data", "perception", "--n", "3", "--out", "d", "--width", "320",
                     "--height", "240", "--no-progress"]) == 0
    assert "wrote 3 frames in 2 shard(s) of up to 2 to d" in capsys.readouterr().out
    assert cli.main(["train", "segmentation", "--data", "d", "--steps", "2", "--batch", "2",
                     "--no-progress"]) == 0
    out = in_tmp / "out" / "train" / "segmentation"
    assert sorted(p.name for p in out.iterdir()) == ["segmentation.json", "segmentation.md",
                                                     "segmentation.pt"]
    assert "mask IoU median" in (out / "segmentation.md").read_text()
    assert _digest(bundled) == before


@pytest.mark.slow
def test_affordances_train_into_out_and_install_keeps_the_metrics(
        in_tmp: Path, affordance_set: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    bundled = affordance_training.installed_weights()
    before = _digest(bundled), _digest(bundled.parent / "MODEL_CARD.md")
    common = ["train", "affordances", "--data", str(affordance_set), "--epochs", "1",
              "--rotations", "1"]
    assert cli.main(common) == 0
    out = in_tmp / "out" / "train" / "affordances"
    assert sorted(p.name for p in out.iterdir()) == ["MODEL_CARD.md", "affordances.pt"]
    assert "Not evaluated (no --test-data)" in (out / "MODEL_CARD.md").read_text()
    # --install targets the bundled files; here they are redirected to a copy's place.
    installed = in_tmp / "package" / "affordances.pt"
    monkeypatch.setattr(affordance_training, "installed_weights", lambda: installed)
    assert cli.main([*common, "--install", "--test-data", str(affordance_set)]) == 0
    card = (installed.parent / "MODEL_CARD.md").read_text()
    assert "| object | push length | predictor |" in card and "| lrn |" in card, card
    assert (_digest(bundled), _digest(bundled.parent / "MODEL_CARD.md")) == before
    capsys.readouterr()


# --- help -------------------------------------------------------------------------------------

def _leaves(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [parser]
    return [leaf for a in subs for p in dict.fromkeys(a.choices.values()) for leaf in _leaves(p)]


def test_help_shows_every_default() -> None:
    leaves = _leaves(cli.build_parser())
    assert len(leaves) > 25
    missing = []
    for parser in leaves:
        formatter = parser._get_formatter()
        for action in parser._actions:
            if (not action.option_strings or action.default in (None, False)
                    or action.default is argparse.SUPPRESS or action.nargs == 0):
                continue
            text = formatter._expand_help(action)
            if "default" not in text.lower():
                missing.append(f"{parser.prog} {action.option_strings[0]}: {text!r}")
    assert not missing, "\n".join(missing)


def test_help_of_train_shows_its_default_output_folder(capsys) -> None:
    with pytest.raises(SystemExit):
        cli.main(["train", "segmentation", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: out/train/segmentation/segmentation.pt)" in text
    assert "--steps STEPS optimiser steps (default 3000; 300 with --init)" in text
