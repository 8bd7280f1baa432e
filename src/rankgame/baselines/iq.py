"""IQ-Learn (Garg et al. 2021): imitation by inverse soft-Q learning, without a learned reward.

SAC learns from batches that are half its own transitions and half the expert's
(:func:`~rankgame.policy.buffer.mix_demonstrations`), and its critic minimizes the inverse soft-Q
objective (:class:`~rankgame.policy.critic_objectives.InverseSoftQ`) instead of a Bellman error against
a reward: the critic becomes the reward model, ``r_Q(s, a) = Q(s, a) - gamma V(s')``. The actor and the
temperature are SAC's, updated on all rows of the mixed batches. :class:`IQTrainer` is the
:class:`~rankgame.run.Trainer` of ``rankgame train --method iq-learn``.

Settings follow the authors' MuJoCo scripts: the ``iq-learn`` SAC preset
(:data:`~rankgame.policy.sac.SAC_PRESETS`: batches of 256 agent + 256 expert rows, actor lr 3e-5, critic
lr 3e-4, fixed temperature 0.01, no random warm-up) and, per task, the ``v0`` or ``value`` form of the
objective (:data:`AUTHORS_VARIANT`) with the chi-squared regularizer on. From observations (``--setting
lfo``) the expert rows take the actions of the agent rows they are paired with, the authors'
``only_expert_states`` option, which the paper tried and found not to learn. Episodes end at true
terminations, as in the authors' code: no absorbing states. ``rankgame export-reward`` writes the reward
the critic implies (:mod:`rankgame.reward.export`, ``kind: soft-q``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from rankgame.baselines.cloning import expert_state_actions, expert_trajectories
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import EnvSpec, env_spec, make_env
from rankgame.envs.rollout import EVAL_SEED_OFFSET
from rankgame.errors import nonfinite_fields, require
from rankgame.policy.critic_objectives import InverseSoftQ
from rankgame.policy.learner import SACLearner
from rankgame.policy.sac import SACConfig
from rankgame.run import POLICY_NAME
from rankgame.scores import EVAL_COLUMNS, ScoreScale, score_postfix

#: The objective's form in the authors' MuJoCo scripts, by task family; every other task gets ``v0``.
AUTHORS_VARIANT: dict[str, Literal["v0", "value"]] = {"HalfCheetah": "value", "Ant": "value"}

#: Columns of an IQ-Learn run's ``metrics.csv``.
IQ_LOG_COLUMNS = (
    *EVAL_COLUMNS,
    "losses/critic",
    "losses/actor",
    "losses/alpha",
    "losses/expert_reward",
    "losses/agent_reward",
    "losses/value",
)


@dataclass(frozen=True)
class IQConfig:
    """IQ-Learn's critic objective (iq-learn only; its SAC settings are the iq-learn preset)."""

    variant: Literal["default", "v0", "value"] = "default"
    """The objective's initial-state term: v0, (1 - gamma) E_expert[V(s)], or value, E[V(s) - gamma V(s')]
    over expert and agent rows; default: the authors' choice for the task (value on HalfCheetah and Ant,
    v0 elsewhere)."""
    chi2_weight: float = 0.5
    """Weight of the chi-squared regularizer, the mean squared implied reward over all rows (the authors'
    1 / (4 alpha) with alpha = 0.5)."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense."""
        require(
            [
                (not nonfinite_fields(self), "iq.chi2_weight must be finite"),
                (self.chi2_weight >= 0.0, "iq.chi2_weight must be >= 0"),
            ]
        )

    def objective(self, env_id: str) -> InverseSoftQ:
        """The critic objective on task ``env_id``."""
        family = env_id.split("/")[-1].split("-")[0]
        variant = AUTHORS_VARIANT.get(family, "v0") if self.variant == "default" else self.variant
        return InverseSoftQ(variant, self.chi2_weight)


def demonstration_transitions(
    trajectories: tuple[Trajectory, ...], spec: EnvSpec, with_actions: bool = True
) -> dict[str, np.ndarray]:
    """The expert's transitions as SAC batch fields, ``(N, ...)`` with ``N = sum T_i``: ``obs``, ``acts`` (in
    the normalized box; left out without ``with_actions``), ``next_obs`` and ``dones`` (1 on a trajectory's
    last step if it terminated).

    Raises:
        RankGameError: the data has no usable actions (:func:`~rankgame.baselines.cloning.expert_state_actions`).
    """
    next_obs = np.concatenate([t.obs[1:] for t in trajectories]).astype(np.float32)
    dones = np.concatenate([t.terminated for t in trajectories]).astype(np.float32)
    if not with_actions:
        obs = np.concatenate([t.obs[:-1] for t in trajectories]).astype(np.float32)
        return {"obs": obs, "next_obs": next_obs, "dones": dones}
    obs, acts = expert_state_actions(trajectories, spec)
    return {"obs": obs, "acts": acts, "next_obs": next_obs, "dones": dones}


class IQTrainer:
    """IQ-Learn as the :class:`~rankgame.run.Trainer` of ``rankgame train --method iq-learn``.

    Args:
        sac: SAC's settings (by default the ``iq-learn`` preset, through the CLI).
        config: the objective's settings.
        env_id: the task.
        expert: the expert data; its first ``n_expert`` trajectories (with actions) are imitated, and its
            returns scale the normalized score.
        n_expert: how many expert trajectories to imitate.
        seed: seeds everything random.
        eval_episodes: episodes per evaluation.
        setting: ``lfd``, or ``lfo``: the expert's actions are not read, and each expert row of a batch takes
            the action of the agent row it is paired with (the authors' ``only_expert_states``).

    Raises:
        RankGameError: an unknown task, or expert data that does not fit it or has no actions.
    """

    def __init__(
        self,
        sac: SACConfig,
        config: IQConfig,
        env_id: str,
        expert: TrajectoryFile,
        n_expert: int,
        seed: int,
        eval_episodes: int,
        setting: Literal["lfd", "lfo"] = "lfd",
    ) -> None:
        self.env_id, self.seed, self.eval_episodes = env_id, seed, eval_episodes
        self.command = ""
        """The command line recorded in saved policies."""
        self.eval_env = make_env(env_id)
        spec = env_spec(self.eval_env)
        trajectories = expert_trajectories(expert, n_expert, spec)
        demonstrations = demonstration_transitions(trajectories, spec, with_actions=setting == "lfd")
        objective = config.objective(env_id)
        self.learner = SACLearner(
            make_env(env_id),
            sac,
            seed,
            store_env_reward=False,
            critic_objective=objective,
            demonstrations=demonstrations,
        )
        self.scale = ScoreScale.of(expert, self.eval_env, seed)
        self.metrics: dict[str, float] = {}

    @property
    def env_steps(self) -> int:
        return self.learner.env_steps

    def step(self, step: int) -> None:
        """One environment step and the SAC updates due after it."""
        self.learner.env_step()
        self.metrics = self.learner.maybe_update() or self.metrics

    def can_checkpoint(self, step: int) -> bool:
        return True

    def evaluate(self) -> dict[str, float]:
        """The deterministic policy's evaluation row (:meth:`~rankgame.scores.ScoreScale.evaluate`)."""
        return self.scale.evaluate(
            self.eval_env, self.learner.policy(), self.eval_episodes, self.seed + EVAL_SEED_OFFSET
        )

    def training_metrics(self) -> dict[str, float]:
        return self.metrics

    def postfix(self, row: dict[str, float]) -> dict[str, str]:
        return score_postfix(row)

    def save_policies(self, out: Path, step: int, row: dict[str, float]) -> None:
        """Write the current actor to ``out / policy.msgpack`` for ``rankgame evaluate``."""
        self.learner.save_policy(
            out / POLICY_NAME, self.env_id, command=self.command, env_steps=step, eval_return=row["eval_return"]
        )

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata, arrays = self.learner.checkpoint()
        return {**metadata, "iq_metrics": self.metrics, "reward_spec": self.reward_spec()}, arrays

    def reward_spec(self) -> dict[str, Any]:
        """What rebuilds the reward the critic implies outside the run (:mod:`rankgame.reward.export`)."""
        spec, config = self.learner.spec, self.learner.config
        return {
            "kind": "soft-q",
            "env_id": self.env_id,
            "input": "sas",
            "absorbing": False,
            "obs_dim": spec.obs_dim,
            "act_dim": spec.act_dim,
            "act_low": spec.act_low.tolist(),
            "act_high": spec.act_high.tolist(),
            "hidden_sizes": list(config.hidden_sizes),
            "gamma": config.gamma,
            "alpha": float(np.exp(self.learner.state.log_alpha)),
        }

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self.learner.restore(metadata, arrays, seed=self.seed + int(metadata["env_steps"]))
        self.metrics = dict(metadata["iq_metrics"])
