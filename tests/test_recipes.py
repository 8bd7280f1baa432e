"""``rankgame train --recipe``: per-task settings that start the defaults and yield to explicit options."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import pytest
from conftest import assert_one_line_error, run_main

from rankgame.cli import train_config_from_argv
from rankgame.config import TrainConfig, config_to_json
from rankgame.errors import RankGameError
from rankgame.game.recipes import TUNED, recipe_settings, setting_value, with_settings


@dataclass(frozen=True)
class _Inner:
    lr: float = 1.0
    decay: float = 2.0


@dataclass(frozen=True)
class _Outer:
    name: str = "a"
    inner: _Inner = field(default_factory=_Inner)


def test_with_settings_sets_top_level_and_nested_fields_by_dotted_name() -> None:
    changed = with_settings(_Outer(), {"name": "b", "inner.lr": 0.5})
    assert changed == _Outer("b", _Inner(0.5, 2.0))
    assert setting_value(changed, "inner.lr") == 0.5 and setting_value(changed, "name") == "b"


def test_paper_changes_nothing_and_tuned_changes_only_listed_pairs() -> None:
    assert recipe_settings("paper", "Ant-v5", "rank-pal-auto") == {}
    assert recipe_settings("tuned", "Ant-v5", "rank-pal-auto") == {"reward_obs": "0:27"}
    assert recipe_settings("tuned", "HalfCheetah-v5", "rank-pal-auto") == {
        "reward.lr": 1e-4,
        "reward.weight_decay": 1e-2,
    }
    assert recipe_settings("tuned", "HalfCheetah-v5", "rank-ral-auto") == {}
    assert recipe_settings("tuned", "Hopper-v5", "rank-ral-auto") == {
        "rankings.k": 1.0,
        "reward.r_max": 1.0,
        "sac.updates_per_step": 2.0,
    }
    assert recipe_settings("tuned", "Walker2d-v5", "rank-pal-auto") == {"leader.patience": 1}
    assert recipe_settings("tuned", "rankgame/AntNoContact-v5", "rank-ral-auto") == {
        "leader.ral_passes": 6.0,
        "sac.updates_per_step": 2.0,
    }
    assert recipe_settings("tuned", "Walker2d-v5", "rank-ral-auto") == {
        "leader.ral_passes": 6.0,
        "sac.updates_per_step": 2.0,
    }
    with pytest.raises(ValueError, match="unknown recipe 'best'"):
        recipe_settings("best", "Ant-v5", "rank-pal-auto")


def test_every_tuned_setting_names_an_existing_option() -> None:
    for (env, method), settings in TUNED.items():
        config = with_settings(TrainConfig(env=env, method=method), settings)  # type: ignore[arg-type]
        config.validate()
        assert all(setting_value(config, name) == value for name, value in settings.items())


def test_the_cli_applies_the_recipe_to_the_defaults_and_explicit_options_win() -> None:
    cfg, note = train_config_from_argv(["--env", "HalfCheetah-v5", "--recipe", "tuned", "--reward.lr", "3e-4"])
    assert cfg.reward.lr == 3e-4 and cfg.reward.weight_decay == 1e-2 and cfg.env == "HalfCheetah-v5"
    assert note == (
        "--recipe tuned for rank-pal-auto on HalfCheetah-v5: "
        "--reward.lr 0.0001 (overridden), --reward.weight-decay 0.01"
    )
    cfg, note = train_config_from_argv(["--recipe=tuned", "--env=Ant-v5", "--method", "rank-ral-auto"])
    assert cfg.reward_obs == "0:27" and cfg.leader.ral_passes == 6.0 and cfg.sac.updates_per_step == 2
    assert note is not None and note.endswith("--reward-obs 0:27, --leader.ral-passes 6.0, --sac.updates-per-step 2.0")
    keeps_paper = ["--recipe", "tuned", "--env", "HalfCheetah-v5", "--method", "rank-ral-auto"]
    cfg, note = train_config_from_argv(keeps_paper)
    assert cfg == TrainConfig(env="HalfCheetah-v5", method="rank-ral-auto")
    assert note is not None and note.endswith("the paper's apply")
    cfg, note = train_config_from_argv(["--recipe", "tuned"])  # the default task and method: Hopper-v5, PAL
    assert cfg.rankings.k == 1.0 and cfg.reward.r_max == 1.0 and cfg.leader.patience == 1
    assert note is not None and note.endswith("--reward.r-max 1.0, --leader.patience 1")
    cfg, note = train_config_from_argv(["--env", "Ant-v5"])
    assert cfg.reward_obs == "all" and note is None
    with pytest.raises(RankGameError, match="unknown recipe"):
        train_config_from_argv(["--recipe", "fancy"])


@pytest.mark.parametrize(
    ("option", "message"),
    [
        ("--recipe", "unknown recipe 'fancy'; choose from paper, tuned"),
        ("--preset", "unknown preset 'fancy'; choose from paper, modern"),
    ],
)
def test_an_unknown_recipe_or_preset_is_a_command_line_error(
    option: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    for args in ([option, "fancy"], [f"{option}=fancy", "--env", "Ant-v5"]):
        result = run_main(capsys, "train", *args, "--out", str(tmp_path / "x"))
        assert_one_line_error(result, message)
        assert result.returncode == 2 and result.stderr.startswith("rankgame train: error: ")
    assert not (tmp_path / "x").exists()


def _saved_run(out: Path, config: TrainConfig) -> Path:
    out.mkdir()
    (out / "config.json").write_text(json.dumps({"command": "rankgame train", **config_to_json(config)}))
    return out


def test_a_resumed_run_takes_the_recipe_of_its_own_task_and_method(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pair = ("HalfCheetah-v5", "rank-pal-auto")
    tuned = with_settings(TrainConfig(env=pair[0], method=pair[1], steps=5000), recipe_settings("tuned", *pair))
    out = _saved_run(tmp_path / "tuned", replace(tuned, out=tmp_path / "tuned"))
    # The command that started it, less --env and --method: the folder says which pair it is.
    cfg, note = train_config_from_argv(["--out", str(out), "--resume", "--recipe", "tuned", "--steps", "6000"])
    assert cfg == replace(tuned, out=out, resume=True, steps=6000) and note is None
    cfg, _ = train_config_from_argv(["--out", str(out), "--resume", "--recipe", "tuned", "--env", pair[0]])
    assert cfg == replace(tuned, out=out, resume=True)
    # --no-resume after --resume starts a fresh run: the recipe is then that of the defaults.
    cfg, _ = train_config_from_argv(["--out", str(out), "--resume", "--no-resume", "--recipe", "tuned"])
    assert cfg.env == "Hopper-v5" and not cfg.resume
    # A run started with the paper's settings keeps them: --recipe tuned on resume is refused by name.
    paper = _saved_run(tmp_path / "paper", TrainConfig(env=pair[0], method=pair[1], out=tmp_path / "paper"))
    refused = run_main(capsys, "train", "--out", str(paper), "--resume", "--recipe", "tuned")
    assert_one_line_error(refused, "--reward.lr 0.0001 differs from the run's 0.001")
