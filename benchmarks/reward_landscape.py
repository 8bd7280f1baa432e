"""Learned reward landscapes on a 2-D state space: the ranking game's reward against GAIL's (the paper,
Sec. 4, Fig. "rank_game_reward_shaping": rank-game (auto) learns a smooth reward, GAIL a steep one).

Expert and agent trajectories are time-aligned paths in the plane (``--horizon`` steps, ``--trajectories``
of each): the expert walks a wave from ``x = -1.5`` to ``1.5`` at ``y ~ 1``, the agent covers half that
distance at ``y = -1``, both with Gaussian noise. Each method's reward player (the package's own
:class:`~rankgame.reward.player.RewardPlayer`, rankings and loss, Table 4's network and optimizer) takes
``--steps`` gradient steps on them:

* ``rank-game (auto)``: L_k on the auto rankings, agent < time-aligned mixtures < expert (SL_k);
* ``rank-game (vanilla)``: L_k on agent < expert alone;
* ``GAIL``: the logistic discriminator, paying the policy ``softplus(logit)`` (GAIL's ``-log(1 - D)``).

Each reward is then normalized to 0 on the agent's states and 1 on the expert's (its means there), and
measured along the segments from each agent state to its time-aligned expert state, ``a + u (e - a)``:

* ``slope_at_agent``: the rise of the mean normalized reward over the first tenth of the way, per unit
  of the way: how strongly the reward points the agent toward the expert where the agent is (a
  straight ramp gives 1, a step at the expert 0);
* ``steepest_tenth``: the largest share of the whole rise taken within one tenth of the way (a ramp
  gives 0.1, a step 1);
* ``gradient_p95``: the 95th percentile of ``|grad r| D`` (``D`` the mean agent-expert distance) over a
  grid covering both, from finite differences: how steep the landscape gets anywhere near the data.

Prints JSON (per seed and, over seeds, n, mean and sample standard deviation); ``--plot FIG`` draws the
three landscapes of the first seed and the mean profiles along the segments. Example (the notebook's
figure)::

    python benchmarks/reward_landscape.py --out benchmarks/results/reward-landscape/landscape.json \\
        --plot docs/img/reward_landscape.png
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jax
import numpy as np
from script_io import emit, refused

from rankgame.absorbing import flag_obs
from rankgame.errors import RankGameError
from rankgame.game.rankings import RankingsConfig, RankingSource, build_rankings
from rankgame.plot import pyplot
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import LOSSES
from rankgame.reward.player import RewardConfig, RewardPlayer
from rankgame.stats import mean_and_sample_std


@dataclass(frozen=True)
class LandscapeMethod:
    """A reward player's rankings and loss, as in :data:`rankgame.game.methods.METHODS`."""

    label: str
    rankings: RankingSource
    loss: str


METHODS = (
    LandscapeMethod("rank-game (auto)", "auto", "regression"),
    LandscapeMethod("rank-game (vanilla)", "vanilla", "regression"),
    LandscapeMethod("GAIL", "vanilla", "logistic"),
)

#: The reward inputs: a 2-D state and its absorbing flag (always 0 here).
LAYOUT = InputLayout(obs_dim=2, act_dim=0, kind="s")
#: Positions ``u`` along each agent-to-expert segment where the profile is measured.
PATH = np.linspace(0.0, 1.0, 51)
#: The plotted and measured square, ``[-EXTENT, EXTENT]^2``, and its grid points per side.
EXTENT, GRID = 2.5, 101
METRICS = ("slope_at_agent", "steepest_tenth", "gradient_p95")
#: ``states (..., 2) -> rewards (...)``.
StateReward = Callable[[np.ndarray], np.ndarray]


def paths(rng: np.random.Generator, trajectories: int, horizon: int, noise: float) -> tuple[np.ndarray, np.ndarray]:
    """Expert and agent states, each ``(trajectories, horizon, 2)`` float32 (see the module docstring)."""
    t = np.linspace(0.0, 1.0, horizon)
    expert_x = -1.5 + 3.0 * t
    expert = np.stack([expert_x, 1.0 + 0.3 * np.sin(np.pi * expert_x)], axis=-1)
    agent = np.stack([-1.5 + 1.5 * t, np.full(horizon, -1.0)], axis=-1)
    shape = (trajectories, horizon, 2)
    jitter = [noise * rng.normal(size=shape) for _ in range(2)]
    return (expert + jitter[0]).astype(np.float32), (agent + jitter[1]).astype(np.float32)


def fit_reward(
    method: LandscapeMethod, expert: np.ndarray, agent: np.ndarray, steps: int, seed: int
) -> tuple[RewardPlayer, Any]:
    """The method's reward player after ``steps`` gradient steps on ``agent`` ranked below ``expert``."""
    loss = LOSSES[method.loss]
    rankings = build_rankings(method.rankings, RankingsConfig(), flag_obs(expert), LAYOUT, 0.0, loss)
    rng = np.random.default_rng(seed)
    rankings.data.add(list(flag_obs(agent)), rng)
    player = RewardPlayer(LAYOUT, loss, RewardConfig(), rankings)
    state, _, _ = player.fit_steps(player.init(jax.random.PRNGKey(seed)), steps, rng)
    return player, state.params


def normalized(player: RewardPlayer, params: Any, expert: np.ndarray, agent: np.ndarray) -> StateReward:
    """``states (..., 2) -> (...)``: the bounded reward the policy is paid, shifted and scaled to 0 at its
    mean over the agent's states and 1 at its mean over the expert's.

    Raises:
        ValueError: the reward does not pay the expert's states more than the agent's.
    """

    def reward(states: np.ndarray) -> np.ndarray:
        flat = flag_obs(states.reshape(-1, 2).astype(np.float32))
        return np.asarray(player.reward(params, flat)).reshape(states.shape[:-1])

    low, high = reward(agent).mean(), reward(expert).mean()
    if not high > low:
        raise ValueError(f"the fitted reward pays the agent {low:.3g} and the expert {high:.3g}: no ranking to measure")
    return lambda states: (reward(states) - low) / (high - low)


def measure(
    reward: StateReward, expert: np.ndarray, agent: np.ndarray
) -> tuple[dict[str, float], np.ndarray, np.ndarray]:
    """The metrics of the module docstring for a normalized ``reward``; also its mean profile ``(len(PATH),)``
    along the segments and its values on the grid ``(GRID, GRID)`` (rows: y, columns: x)."""
    segments = agent[..., None, :] + PATH[:, None] * (expert - agent)[..., None, :]  # (M, H, U, 2)
    profile = reward(segments).mean(axis=(0, 1))
    tenth = int(round(0.1 * (len(PATH) - 1)))
    rise = profile[-1] - profile[0]
    axis = np.linspace(-EXTENT, EXTENT, GRID)
    xs, ys = np.meshgrid(axis, axis)
    grid = reward(np.stack([xs, ys], axis=-1))
    d_y, d_x = np.gradient(grid, axis, axis)
    distance = float(np.linalg.norm(expert - agent, axis=-1).mean())
    metrics = {
        "slope_at_agent": float((profile[tenth] - profile[0]) / PATH[tenth]),
        "steepest_tenth": float(np.max(profile[tenth:] - profile[:-tenth]) / rise),
        "gradient_p95": float(np.quantile(np.hypot(d_x, d_y) * distance, 0.95)),
    }
    return metrics, profile, grid


def study(
    seeds: list[int], steps: int, trajectories: int, horizon: int, noise: float
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Every method on every seed: per method its metrics and mean profile (JSON), and its normalized
    reward on the grid ``(GRID, GRID)`` for the first seed."""
    per_method: dict[str, Any] = {}
    first_grids: dict[str, np.ndarray] = {}
    for method in METHODS:
        runs, profiles = [], []
        for seed in seeds:
            expert, agent = paths(np.random.default_rng(seed), trajectories, horizon, noise)
            player, params = fit_reward(method, expert, agent, steps, seed)
            metrics, profile, grid = measure(normalized(player, params, expert, agent), expert, agent)
            runs.append({"seed": seed, **metrics})
            profiles.append(profile)
            first_grids.setdefault(method.label, grid)
        summary = {}
        for name in METRICS:
            mean, std = mean_and_sample_std([run[name] for run in runs])
            summary[name] = {"n": len(runs), "mean": mean, "std": std}
        per_method[method.label] = {
            "rankings": method.rankings,
            "loss": method.loss,
            "summary": summary,
            "runs": runs,
            "profile": np.mean(profiles, axis=0).tolist(),
        }
    return per_method, first_grids


def plot_study(
    per_method: dict[str, Any],
    grids: dict[str, np.ndarray],
    seed: int,
    trajectories: int,
    horizon: int,
    noise: float,
    out: Path,
) -> None:
    """The first seed's three normalized landscapes with the data on them, and the mean profiles."""
    plt = pyplot()
    expert, agent = paths(np.random.default_rng(seed), trajectories, horizon, noise)
    fig, axes = plt.subplots(1, len(per_method) + 1, figsize=(4.2 * (len(per_method) + 1), 3.8))
    for axis, (label, grid) in zip(axes, grids.items(), strict=False):
        extent = (-EXTENT, EXTENT, -EXTENT, EXTENT)
        image = axis.imshow(grid, origin="lower", extent=extent, cmap="viridis", vmin=-0.5, vmax=1.5)
        axis.plot(*agent.reshape(-1, 2).T, ".", color="hotpink", ms=2, label="agent")
        axis.plot(*expert.reshape(-1, 2).T, ".", color="black", ms=2, label="expert")
        axis.set_title(f"{label}, seed {seed}", fontsize=9)
        axis.set_xticks([])
        axis.set_yticks([])
    fig.colorbar(image, ax=axes[: len(per_method)], shrink=0.8, label="reward (agent 0, expert 1)")
    axes[0].legend(fontsize=7, loc="lower right")
    for label, result in per_method.items():
        axes[-1].plot(PATH, result["profile"], label=label)
    axes[-1].set_xlabel("way u from an agent state to its expert state")
    axes[-1].set_ylabel("mean normalized reward")
    axes[-1].legend(fontsize=7)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110, bbox_inches="tight")


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="seeds of data and rewards")
    parser.add_argument("--steps", type=int, default=2000, help="reward gradient steps per method")
    parser.add_argument("--trajectories", type=int, default=4, help="expert and agent trajectories each")
    parser.add_argument("--horizon", type=int, default=40, help="states per trajectory")
    parser.add_argument("--noise", type=float, default=0.05, help="standard deviation of the states' noise")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    parser.add_argument("--plot", type=Path, help="also draw the landscapes here (PNG)")
    args = parser.parse_args(argv)
    problems = [
        (args.steps < 1 or args.trajectories < 1, "--steps and --trajectories must be positive"),
        (args.horizon < 2, "--horizon must be at least 2"),
        (not 0.0 <= args.noise < 1.0, "--noise must lie in [0, 1)"),
    ]
    if refused("reward_landscape.py", problems):
        return 1
    try:
        if args.plot is not None:
            pyplot()  # a missing plot extra fails here, before any work
        per_method, grids = study(args.seeds, args.steps, args.trajectories, args.horizon, args.noise)
    except (ValueError, RankGameError) as exc:
        print(f"reward_landscape.py: {exc}", file=sys.stderr)
        return 1
    if args.plot is not None:
        plot_study(per_method, grids, args.seeds[0], args.trajectories, args.horizon, args.noise, args.plot)
    result = {
        "command": "python benchmarks/reward_landscape.py " + " ".join(argv),
        "steps": args.steps,
        "seeds": args.seeds,
        "methods": per_method,
    }
    emit(result, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
