"""``rankgame evaluate``: the true return and normalized score of a saved policy.

The policy is rolled out on its own task for a number of episodes (episode ``i`` reset with
``seed + i``), deterministically by default, as the training loop's evaluations do. Scores are
normalized with the expert and random returns of an expert data file: ``--expert FILE``, or the
shipped data of the policy's task when there is any.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rankgame.data.experts import load_expert_data, normalized_score, shipped_envs, shipped_expert_path
from rankgame.envs.make import make_env
from rankgame.envs.rollout import episode_succeeded, run_episodes, success_rate
from rankgame.errors import RankGameError
from rankgame.policy.io import load_policy


@dataclass(frozen=True)
class EvaluateConfig:
    """Options of ``rankgame evaluate``."""

    policy: Path = Path("runs/train/policy.msgpack")
    """Saved policy (written by rankgame train or rankgame expert)."""
    episodes: int = 10
    """Episodes to roll out."""
    seed: int = 0
    """Seed of the first episode's reset (episode i uses seed + i)."""
    stochastic: bool = False
    """Sample actions from the policy instead of taking its mean action."""
    expert: Path | None = None
    """Expert data whose expert and random returns normalize the score (default: the shipped data of the task)."""

    def validate(self) -> None:
        if self.episodes <= 0:
            raise RankGameError(f"--episodes must be positive (got {self.episodes})")
        if self.seed < 0:
            raise RankGameError(f"--seed must be >= 0 (got {self.seed})")


def evaluate_policy(cfg: EvaluateConfig) -> dict[str, Any]:
    """Roll out the policy and summarize its returns ``(episodes,)``, with each episode's return and
    success in episode order; ``normalized_score`` is None when no expert data is known for the task,
    ``success_rate`` and ``episode_successes`` when the task reports no success."""
    cfg.validate()
    saved = load_policy(cfg.policy)
    has_expert = cfg.expert is not None or saved.env_id in shipped_envs()
    expert = load_expert_data(cfg.expert, saved.env_id) if has_expert else None

    env = make_env(saved.env_id)
    policy = saved.policy_fn(deterministic=not cfg.stochastic, seed=cfg.seed)
    episodes, success_steps = run_episodes(env, policy, cfg.episodes, cfg.seed)
    env.close()
    returns = np.array([episode.ret for episode in episodes])
    summary: dict[str, Any] = {
        "env": saved.env_id,
        "policy": str(cfg.policy),
        "episodes": cfg.episodes,
        "deterministic": not cfg.stochastic,
        "return_mean": float(returns.mean()),
        "return_std": float(returns.std()),
        "return_min": float(returns.min()),
        "return_max": float(returns.max()),
        "mean_length": float(np.mean([len(episode) for episode in episodes])),
        "success_rate": success_rate(success_steps),
        "normalized_score": None,
        "episode_returns": returns.tolist(),
        "episode_successes": None if None in success_steps else [episode_succeeded(s) for s in success_steps],
    }
    if expert is not None:
        expert_return = float(expert.returns.mean())
        random_return = float(expert.metadata.get("random_return_mean", np.nan))
        score = float(normalized_score(summary["return_mean"], expert_return, random_return))
        summary.update(
            normalized_score=score if np.isfinite(score) else None,
            expert_file=str(cfg.expert or shipped_expert_path(saved.env_id)),
            expert_return=expert_return,
            random_return=random_return if np.isfinite(random_return) else None,
        )
    return summary
