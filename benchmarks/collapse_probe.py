"""What the learned reward and the critic say before, during and after a collapse.

Trains one ranking-game run exactly as ``rankgame train`` would with the same options and, at every
evaluation, writes one row of ``OUT/probe.csv`` measured on the run's current reward and SAC:

* ``reward_expert``: mean learned reward over the expert's transitions (the data imitated);
* ``reward_policy``: mean learned reward over one deterministic episode of the current policy (a
  fixed seed), with ``policy_length`` its length and ``policy_true_per_step`` its mean true reward
  per step (on Hopper-v5 about 1 when it stands still, the healthy bonus alone, and 3 or more when
  it hops like the expert);
* ``reward_stand``: learned reward of standing still at the initial pose, the transition
  ``(s_0, s_0)``; ``reward_absorbing``: the learned reward of the absorbing state;
* ``q_start``: ``min_i Q_i(s_0, pi(s_0))``, the critic's value of the first state under the current
  policy, beside ``stand_forever = reward_stand / (1 - gamma)`` and
  ``expert_forever = reward_expert / (1 - gamma)``, the values of standing still and of collecting the
  expert's mean reward for ever;
* ``q_expert``: mean ``min_i Q_i(s, pi(s))`` over the expert's states.

Rewards are on the learned reward's scale (regressed to ``[0, k]`` by the rank methods, bounded to
``[-r_max, r_max]``). ``--plot FIG`` draws the
normalized score, the rewards and the values against steps from ``probe.csv`` (matplotlib, the
``plot`` extra). ``--summary CSV...`` prints, as JSON, what each probe says before its collapses: for
every evaluation after the run first reached 80 whose previous evaluation was not itself a collapse
(below 50), whether it collapsed, ``stand_over_policy``, the previous evaluation's ``reward_stand /
reward_policy`` (how the reward the policy saw paid standing still against what it did), and the
probe episode's length and true reward per step (a whole episode at the healthy bonus alone is
standing still; a short one is a fall). Examples::

    python benchmarks/collapse_probe.py --env Hopper-v5 --method rank-pal-auto --seed 0 \\
        --steps 300000 --no-tensorboard --out runs/probe/Hopper-v5__rank-pal-auto__s0
    python benchmarks/collapse_probe.py --plot docs/img/collapse-probe.png \\
        --probe runs/probe/Hopper-v5__rank-pal-auto__s0/probe.csv
    python benchmarks/collapse_probe.py --summary runs/probe/*/probe.csv

Only the games whose policy player is SAC (the rank and IMIT methods, DAC, DACfO, T-REX, f-IRL) can
be probed. A resumed run appends to its ``probe.csv``.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path
from typing import Any

import jax.numpy as jnp
import numpy as np

import rankgame.training as training
from rankgame.absorbing import absorbing_obs, flag_obs
from rankgame.cli import train_config_from_argv
from rankgame.data.trajectories import Trajectory
from rankgame.envs.make import make_env
from rankgame.envs.rollout import rollout
from rankgame.errors import RankGameError
from rankgame.game.loop import RankingGame
from rankgame.game.methods import METHODS
from rankgame.plot import pyplot

PROBE_COLUMNS = (
    "env_steps",
    "normalized_score",
    "reward_expert",
    "reward_policy",
    "reward_stand",
    "reward_absorbing",
    "policy_length",
    "policy_true_per_step",
    "q_start",
    "q_expert",
    "stand_forever",
    "expert_forever",
)
#: Seed of the probe's own policy episode (apart from the run's evaluation seeds).
PROBE_SEED = 424242


def _normalized_actions(acts: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Environment actions ``(T, act_dim)`` mapped to SAC's ``[-1, 1]``."""
    return (2.0 * (acts - low) / (high - low) - 1.0).astype(np.float32)


def _transitions(trajectories: list[Trajectory], low: np.ndarray, high: np.ndarray) -> dict[str, np.ndarray]:
    """The flagged transitions ``obs``, ``next_obs`` ``(N, obs_dim + 1)`` and ``acts`` ``(N, act_dim)``."""
    return {
        "obs": np.concatenate([flag_obs(t.obs[:-1].astype(np.float32)) for t in trajectories]),
        "next_obs": np.concatenate([flag_obs(t.obs[1:].astype(np.float32)) for t in trajectories]),
        "acts": np.concatenate([_normalized_actions(t.acts, low, high) for t in trajectories]),
    }


class Probe:
    """The evaluation callback that measures ``game`` (see the module docstring) into ``path``."""

    def __init__(self, game: RankingGame, expert: list[Trajectory], path: Path) -> None:
        self.game = game
        self.path = path
        spec = game.spec
        self.low, self.high = spec.act_low, spec.act_high
        self.expert = _transitions(expert, self.low, self.high)
        self.env = make_env(game.env_id)
        start, _ = self.env.reset(seed=PROBE_SEED)
        s0 = flag_obs(np.asarray(start, np.float32))[None]
        self.stand = {"obs": s0, "next_obs": s0, "acts": np.zeros((1, spec.act_dim), np.float32)}
        s_abs = absorbing_obs(spec.obs_dim)[None]
        self.absorbing = {"obs": s_abs, "next_obs": s_abs, "acts": self.stand["acts"]}
        if not path.exists() or path.stat().st_size == 0:
            path.write_text(",".join(PROBE_COLUMNS) + "\n")

    def _reward(self, batch: dict[str, np.ndarray]) -> float:
        params = self.game.reward_state.params
        jax_batch = {name: jnp.asarray(value) for name, value in batch.items()}
        return float(jnp.mean(self.game.player.reward_fn(params, jax_batch)))

    def _q_of_policy(self, obs: np.ndarray) -> float:
        """Mean ``min_i Q_i(s, pi(s))`` over flagged states ``(N, obs_dim + 1)``."""
        sac, state = self.game.learner.sac, self.game.learner.state
        obs = jnp.asarray(obs)
        acts = sac.act(state.actor_params, obs, jnp.zeros((obs.shape[0], sac.act_dim)))
        return float(jnp.mean(jnp.min(sac.critic.apply(state.critic_params, obs, acts), axis=0)))

    def __call__(self, step: int, row: dict[str, float]) -> bool:
        episode = rollout(self.env, self.game.learner.policy(), 1, seed=PROBE_SEED)[0]
        gamma = self.game.learner.sac.config.gamma
        reward_expert, reward_stand = self._reward(self.expert), self._reward(self.stand)
        values = {
            "env_steps": step,
            "normalized_score": row["normalized_score"],
            "reward_expert": reward_expert,
            "reward_policy": self._reward(_transitions([episode], self.low, self.high)),
            "reward_stand": reward_stand,
            "reward_absorbing": self._reward(self.absorbing),
            "policy_length": len(episode.acts),
            "policy_true_per_step": float(np.mean(episode.rews)),
            "q_start": self._q_of_policy(self.stand["obs"]),
            "q_expert": self._q_of_policy(self.expert["obs"]),
            "stand_forever": reward_stand / (1.0 - gamma),
            "expert_forever": reward_expert / (1.0 - gamma),
        }
        with self.path.open("a", newline="") as handle:
            csv.writer(handle).writerow([f"{values[name]:.6g}" for name in PROBE_COLUMNS])
        return True


def train_with_probe(argv: list[str]) -> dict[str, Any]:
    """Run ``rankgame train ARGV`` with the probe as its evaluation callback; returns the run's summary."""
    config, _ = train_config_from_argv(argv)
    method = METHODS.get(config.method)
    if method is None or method.policy != "sac":
        raise RankGameError(f"--method {config.method}: only games with the SAC policy player can be probed")
    built: list[RankingGame] = []
    build_trainer = training.build_trainer

    def build_and_keep(*args: Any, **kwargs: Any) -> Any:
        trainer, columns = build_trainer(*args, **kwargs)
        built.append(trainer)
        return trainer, columns

    probe: list[Probe] = []

    def callback(step: int, row: dict[str, float]) -> bool:
        if not probe:
            expert, _ = training.expert_data(config, None)
            trajectories = list(expert.trajectories[: config.expert_trajectories])
            probe.append(Probe(built[0], trajectories, Path(config.out) / "probe.csv"))
        return probe[0](step, row)

    training.build_trainer = build_and_keep
    try:
        return training.train(config, callback=callback, command="rankgame train " + " ".join(argv))
    finally:
        training.build_trainer = build_trainer


def plot_probe(probe_csv: Path, out: Path, title: str | None) -> None:
    """Three panels against steps: the normalized score, the rewards and the values."""
    plt = pyplot()
    column = _read_probe(probe_csv)
    steps = column["env_steps"] / 1000
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    axes[0].plot(steps, column["normalized_score"], "k-o", ms=3)
    axes[0].axhline(80, color="g", lw=0.6, ls="--")
    axes[0].axhline(50, color="r", lw=0.6, ls="--")
    axes[0].set_ylabel("normalized score")
    rewards = (("reward_expert", "b-"), ("reward_policy", "k-"), ("reward_stand", "r-"), ("reward_absorbing", "m:"))
    for name, style in rewards:
        axes[1].plot(steps, column[name], style, label=name.removeprefix("reward_"))
    axes[1].set_ylabel("learned reward")
    axes[1].legend(fontsize=8, ncol=4)
    for name, style in (("q_start", "k-"), ("q_expert", "b-"), ("stand_forever", "r--"), ("expert_forever", "b--")):
        axes[2].plot(steps, column[name], style, label=name)
    axes[2].set_ylabel("value")
    axes[2].set_xlabel("environment steps (thousands)")
    axes[2].legend(fontsize=8, ncol=2)
    if title:
        axes[0].set_title(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


def _read_probe(probe_csv: Path) -> dict[str, np.ndarray]:
    with probe_csv.open() as handle:
        rows = list(csv.DictReader(handle))
    if not rows:
        raise RankGameError(f"{probe_csv}: no probe rows")
    return {name: np.array([float(r[name]) for r in rows]) for name in PROBE_COLUMNS}


def collapse_kind(length: int, horizon: int, true_per_step: float, stand_per_step: float) -> str:
    """What the probe episode of a collapsed evaluation did: ``fall`` (it ended before ``horizon``, the
    longest probe episode of the run), ``stand`` (it lasted but earned less than ``stand_per_step`` true
    reward per step: on Hopper-v5 and Walker2d-v5 the healthy bonus is 1) or ``other``."""
    if length < horizon:
        return "fall"
    return "stand" if true_per_step < stand_per_step else "other"


def probe_learned_return(column: dict[str, np.ndarray], horizon: int) -> np.ndarray:
    """Per evaluation ``(E,)``: the learned return of the probe episode over ``horizon`` steps (the
    absorbing state's reward after an early end) as a share of the expert's under the same reward,
    ``(r_policy L + r_absorbing (H - L)) / (r_expert H)``; NaN where the expert's reward is not positive.
    It uses no true reward; the runs' own criterion (:mod:`rankgame.game.selection`) is the same on the
    evaluation episodes, and probes older than it have only this one."""
    length = column["policy_length"]
    learned = column["reward_policy"] * length + column["reward_absorbing"] * (horizon - length)
    expert = column["reward_expert"] * horizon
    return np.where(expert > 0, learned / np.where(expert > 0, expert, 1.0), np.nan)


def summarize_probe(
    probe_csv: Path, reach: float = 80.0, below: float = 50.0, stand_per_step: float = 1.2
) -> dict[str, Any]:
    """The evaluations after first reaching ``reach`` that follow one at ``below`` or more: their steps,
    whether they fell below ``below``, the previous evaluation's ``reward_stand / reward_policy``, and
    for the collapses what the probe episode did (:func:`collapse_kind`)."""
    column = _read_probe(probe_csv)
    score = column["normalized_score"]
    reached = np.flatnonzero(score >= reach)
    horizon = int(column["policy_length"].max())
    rows = []
    for i in range(int(reached[0]) + 1 if len(reached) else len(score), len(score)):
        if score[i - 1] < below:
            continue
        rows.append(
            {
                "env_steps": int(column["env_steps"][i]),
                "normalized_score": round(float(score[i]), 1),
                "collapsed": bool(score[i] < below),
                "stand_over_policy": round(float(column["reward_stand"][i - 1] / column["reward_policy"][i - 1]), 3),
                "policy_length": int(column["policy_length"][i]),
                "policy_true_per_step": round(float(column["policy_true_per_step"][i]), 2),
            }
        )
    ratios = {flag: [r["stand_over_policy"] for r in rows if r["collapsed"] == flag] for flag in (True, False)}
    kinds = [
        collapse_kind(r["policy_length"], horizon, r["policy_true_per_step"], stand_per_step)
        for r in rows
        if r["collapsed"]
    ]
    ratio = probe_learned_return(column, horizon)
    pick = len(ratio) - 1 - int(np.nanargmax(ratio[::-1]))  # the latest of the best
    return {
        "probe": str(probe_csv),
        "final_score": round(float(score[-1]), 1),
        "selected": {
            "env_steps": int(column["env_steps"][pick]),
            "normalized_score": round(float(score[pick]), 1),
            "learned_return_ratio": round(float(ratio[pick]), 3),
        },
        "collapses": len(ratios[True]),
        "others": len(ratios[False]),
        "collapse_kinds": {kind: kinds.count(kind) for kind in ("stand", "fall", "other")},
        "stand_over_policy_before_collapses": ratios[True],
        "stand_over_policy_before_others": ratios[False],
        "rows": rows,
    }


def main(argv: list[str]) -> int:
    if argv[:1] == ["--summary"]:
        try:
            print(json.dumps([summarize_probe(Path(path)) for path in argv[1:]], indent=1))
        except (OSError, KeyError, ValueError, RankGameError) as exc:
            print(f"collapse_probe: {exc}", file=sys.stderr)
            return 1
        return 0
    if "--plot" in argv:
        parser = argparse.ArgumentParser(description="Plot a probe.csv written by this script.")
        parser.add_argument("--plot", type=Path, required=True, help="image to write (.png, .svg)")
        parser.add_argument("--probe", type=Path, required=True, help="the probe.csv of a run")
        parser.add_argument("--title")
        args = parser.parse_args(argv)
        try:
            plot_probe(args.probe, args.plot, args.title)
        except (OSError, KeyError, ValueError, RankGameError) as exc:
            print(f"collapse_probe: {exc}", file=sys.stderr)
            return 1
        return 0
    try:
        summary = train_with_probe(argv)
    except RankGameError as exc:
        print(f"collapse_probe: {exc}", file=sys.stderr)
        return 1
    print(summary)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
