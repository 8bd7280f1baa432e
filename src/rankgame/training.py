"""``train``: run (or resume) the ranking game from a :class:`~rankgame.config.TrainConfig`.

The one entry point of ``rankgame train`` and of the Python API::

    from rankgame import TrainConfig, train
    summary = train(TrainConfig(env="Hopper-v5", steps=50_000, out="runs/demo"), callback=lambda step, row: True)
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
from pathlib import Path
from typing import Any

from rankgame.baselines.bco import BCO_LOG_COLUMNS, BCOTrainer
from rankgame.baselines.cloning import BC_LOG_COLUMNS, BCTrainer
from rankgame.baselines.iq import IQ_LOG_COLUMNS, IQTrainer
from rankgame.config import TrainConfig, config_to_json
from rankgame.data.trajectories import TrajectoryFile
from rankgame.envs.make import EnvSpec, env_spec, make_env
from rankgame.game.data import DataSource, resolve_expert, resolve_preferences
from rankgame.game.loop import RankingGame
from rankgame.game.methods import METHODS
from rankgame.game.selection import SELECTED_POLICY_NAME, selected_evaluation
from rankgame.game.switch import plan_switch
from rankgame.run import Callback, RunSettings, Trainer, open_run, run


def expert_data(config: TrainConfig, expert: DataSource) -> tuple[TrajectoryFile, EnvSpec]:
    """The expert data of ``config`` (or ``expert``, see :func:`train`) checked against the task, and its spec."""
    env = make_env(config.env)
    spec = env_spec(env)
    env.close()
    source = expert if expert is not None else config.expert
    return resolve_expert(source, config.env, spec, config.expert_trajectories, "expert data"), spec


def build_trainer(
    config: TrainConfig,
    expert: DataSource = None,
    preferences: DataSource = None,
    switch_expert: DataSource = None,
) -> tuple[Trainer, tuple[str, ...]]:
    """The trainer of ``config.method`` (the ranking game, or a method's own) and its log columns."""
    if config.method == "bc":
        data, _ = expert_data(config, expert)
        bc = BCTrainer(config.cloning, config.env, data, config.expert_trajectories, config.seed, config.eval_episodes)
        return bc, BC_LOG_COLUMNS
    if config.method == "bco":
        data, _ = expert_data(config, expert)
        args = (config.cloning, config.env, data, config.expert_trajectories, config.seed, config.eval_episodes)
        return BCOTrainer(*args, steps=config.steps), BCO_LOG_COLUMNS
    if config.method == "iq-learn":
        data, _ = expert_data(config, expert)
        args = (config.env, data, config.expert_trajectories, config.seed, config.eval_episodes)
        return IQTrainer(config.sac, config.iq, *args, setting=config.resolved_setting), IQ_LOG_COLUMNS
    game = build_game(config, expert, preferences, switch_expert)
    return game, game.log_columns


def build_game(
    config: TrainConfig,
    expert: DataSource = None,
    preferences: DataSource = None,
    switch_expert: DataSource = None,
) -> RankingGame:
    """The :class:`~rankgame.game.loop.RankingGame` of ``config`` with its data resolved (see :func:`train`
    for the data arguments); ``config`` must be valid and name a game method."""
    data, spec = expert_data(config, expert)
    prefs = None
    if METHODS[config.method].uses_preferences:
        prefs = resolve_preferences(preferences if preferences is not None else config.preferences, config.env, spec)
    return RankingGame(config, data, prefs, plan_switch(config, spec, switch_expert))


def train(
    config: TrainConfig,
    *,
    expert: DataSource = None,
    preferences: DataSource = None,
    switch_expert: DataSource = None,
    callback: Callback | None = None,
    command: str | None = None,
) -> dict[str, Any]:
    """Run the ranking game to ``config.steps`` (continuing the run in ``config.out`` with ``config.resume``).

    Args:
        config: every setting of the run; ``config.out`` is its folder.
        expert: the expert data to imitate, overriding ``config.expert``: a path (or ``minari:ID``), a
            :class:`~rankgame.data.trajectories.TrajectoryFile` or a sequence of trajectories.
        preferences: the pref methods' offline trajectories, overriding ``config.preferences``.
        switch_expert: the expert after ``config.switch.at``, overriding ``config.switch.expert``.
        callback: ``callback(step, row)`` after every evaluation, with the metrics row logged to
            ``metrics.csv``; returning False stops the run (after a checkpoint: it can be resumed).
        command: the command line recorded in ``config.json`` and saved policies (default: ``sys.argv``).
    Returns:
        ``env``, ``method``, ``steps``, ``env_steps`` (reached), ``stopped_early``, ``out`` and the last
        evaluation's ``eval_return``, ``normalized_score`` (and ``eval_success`` where the task reports it);
        for the game methods also ``selected_policy``: the policy chosen by its learned return
        (:mod:`rankgame.game.selection`), its file, step, criterion and normalized score.
    Raises:
        RankGameError: a one-line reason for bad settings or data, a run that produced a non-finite
            value, or one stopped by a signal (:class:`~rankgame.errors.RunInterrupted`).
    """
    config = dataclasses.replace(config, out=Path(config.out))
    config.validate()
    as_json = config_to_json(config)
    if expert is not None and not isinstance(expert, str | Path):
        as_json["expert"] = "(in memory)"
    settings = RunSettings(
        config.out,
        config.steps,
        config.eval_every,
        config.checkpoint_every,
        config.resume,
        config.tensorboard,
        config.progress,
        f"{config.method} {config.env}",
        config.wandb,
    )
    if config.wandb:  # before anything is written
        from rankgame.tracking import require_wandb

        require_wandb()
    resumed = open_run(settings, as_json)
    # Bad tasks or data fail before OUT exists.
    trainer, columns = build_trainer(config, expert, preferences, switch_expert)
    trainer.command = command or shlex.join(sys.argv)
    row = run(trainer, settings, resumed, as_json, columns, trainer.command, callback)
    keys = ("eval_return", "normalized_score", "eval_success")
    summary = {
        "env": trainer.env_id,
        "method": config.method,
        "steps": config.steps,
        "env_steps": row["env_steps"],
        "stopped_early": row["stopped_early"],
        "out": str(config.out),
        **{key: row[key] for key in keys if key in row},
    }
    selected = selected_evaluation(config.out, since=config.switch.at or 0)
    if selected is not None:
        summary["selected_policy"] = {
            "path": str(config.out / SELECTED_POLICY_NAME),
            "env_steps": selected.env_steps,
            "learned_return": selected.learned_return,
            "normalized_score": selected.normalized_score,
        }
    return summary
