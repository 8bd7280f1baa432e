"""The ranking dataset: agent and expert trajectories and the (auto) mixtures between them.

Rows are time steps ``(i, t)`` of agent trajectories. A sampled training input is the time-aligned
mixture (App. B.1) ``x = a_i[t] + lambda_p (e_j[t] - a_i[t])`` of agent trajectory ``i`` and a
uniformly drawn expert trajectory ``j``, at a uniformly drawn grid point ``p``; its regression
target is ``k_p``. Sampling ``p`` uniformly weights every behavior in the ranking chain equally,
as in SL_k (Eq. 8). The vanilla ranking is the grid ``{0, 1}``: agent vs expert.

With ``time_aligned=False`` the expert state is drawn from a uniformly random time step instead:
the *state-based* mixup that the paper compares against its trajectory mixup (App. D, effect of
the regularizer).

Mixtures are formed when sampled, so memory grows with the agent data only, not with the grid.
A random (shuffled) ``holdout_fraction`` of rows, drawn as rows arrive, is kept out of training: the
leader judges convergence on it (:mod:`rankgame.game.leaders`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rankgame.reward.inputs import InputLayout


class RankingData:
    """Agent trajectories ranked below expert trajectories, with mixture grid and targets.

    Args:
        expert: ``(M, H, d)`` expert reward inputs.
        lambdas: ``(G,)`` mixture weights, ``0`` (agent) first and ``1`` (expert) last.
        targets: ``(G,)`` regression target of each mixture (non-decreasing).
        holdout_fraction: share of agent rows kept out of training.
        layout: the reward inputs' layout, to count real (non-padding) states; ``None`` counts every
            row as real.
        time_aligned: mix agent step ``t`` with expert step ``t`` (trajectory mixup, the paper's auto
            rankings) or with an expert step drawn uniformly from ``[0, H)`` (state mixup).
    """

    def __init__(
        self,
        expert: np.ndarray,
        lambdas: np.ndarray,
        targets: np.ndarray,
        holdout_fraction: float,
        layout: InputLayout | None = None,
        time_aligned: bool = True,
    ) -> None:
        if expert.ndim != 3 or len(expert) == 0:
            raise ValueError(f"expert inputs must have shape (M, H, d) with M >= 1, got {expert.shape}")
        if lambdas.shape != targets.shape or lambdas[0] != 0.0 or lambdas[-1] != 1.0:
            raise ValueError("the mixture grid must run from 0 (agent) to 1 (expert) with one target per point")
        if np.any(np.diff(targets) < 0):
            raise ValueError("ranking targets must be non-decreasing from agent to expert")
        if not 0.0 <= holdout_fraction <= 0.5:
            raise ValueError("holdout_fraction must lie in [0, 0.5]")
        self.expert = expert.astype(np.float32)
        self.lambdas = lambdas.astype(np.float32)
        self.targets = targets.astype(np.float32)
        self.holdout_fraction = holdout_fraction
        self.layout = layout
        self.time_aligned = time_aligned
        self.horizon, self.dim = expert.shape[1], expert.shape[2]
        self.agent = np.zeros((0, self.horizon, self.dim), np.float32)
        self.train_rows = np.zeros((0, 2), np.int64)
        # (i, t, expert j, expert step), fixed for a stable holdout
        self.holdout_rows = np.zeros((0, 4), np.int64)
        self.n_real_states = 0  # agent states that are not absorbing padding

    @property
    def n_trajectories(self) -> int:
        return len(self.agent)

    def clear(self) -> None:
        """Forget all agent data (PAL keeps only the current iteration's)."""
        self.agent = self.agent[:0]
        self.n_real_states = 0
        self.train_rows = self.train_rows[:0]
        self.holdout_rows = self.holdout_rows[:0]

    def add(self, trajectories: Sequence[np.ndarray], rng: np.random.Generator, real_only: bool = False) -> None:
        """Append agent trajectories, each ``(H, d)``, assigning their rows to train or holdout at random;
        with ``real_only``, the rows that start in the absorbing state are not ranked at all."""
        if not trajectories:
            return
        new = np.stack(trajectories).astype(np.float32)
        if new.shape[1:] != (self.horizon, self.dim):
            raise ValueError(f"agent inputs have shape {new.shape[1:]}, expected {(self.horizon, self.dim)}")
        first = len(self.agent)
        self.agent = np.concatenate([self.agent, new])
        real = self.layout.is_real(new) if self.layout is not None else np.ones(new.shape[:2], bool)
        self.n_real_states += int(real.sum())
        idx, t = np.meshgrid(np.arange(first, len(self.agent)), np.arange(self.horizon), indexing="ij")
        rows = np.stack([idx.ravel(), t.ravel()], axis=1)
        if real_only:
            rows = rows[real.ravel()]
        held = rng.uniform(size=len(rows)) < self.holdout_fraction
        experts = rng.integers(0, len(self.expert), size=int(held.sum()))
        expert_steps = self._expert_steps(rng, rows[held, 1])
        self.train_rows = np.concatenate([self.train_rows, rows[~held]])
        self.holdout_rows = np.concatenate([self.holdout_rows, np.column_stack([rows[held], experts, expert_steps])])

    def replace_expert(self, expert: np.ndarray, rng: np.random.Generator) -> None:
        """Rank the agent below other expert trajectories ``(M', H, d)`` from now on (a changed intent);
        the holdout rows are paired with the new experts."""
        if expert.ndim != 3 or len(expert) == 0 or expert.shape[1:] != self.expert.shape[1:]:
            raise ValueError(f"new expert inputs have shape {expert.shape}, expected (M, {self.horizon}, {self.dim})")
        self.expert = expert.astype(np.float32)
        self.holdout_rows[:, 2] = rng.integers(0, len(expert), size=len(self.holdout_rows))

    def _expert_steps(self, rng: np.random.Generator, t: np.ndarray) -> np.ndarray:
        """Expert time step mixed with agent step ``t`` (any shape): ``t`` itself, or a uniform draw."""
        return t if self.time_aligned else rng.integers(0, self.horizon, size=t.shape)

    def _mix(
        self, agent_idx: np.ndarray, t: np.ndarray, expert_idx: np.ndarray, expert_t: np.ndarray, group: np.ndarray
    ) -> np.ndarray:
        a = self.agent[agent_idx, t]
        e = self.expert[expert_idx, expert_t]
        return a + self.lambdas[group][..., None] * (e - a)

    def sample(
        self, rng: np.random.Generator, n_batches: int, batch_size: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Training batches: inputs ``(n, B, d)``, targets ``(n, B)``, is-expert flags ``(n, B)``."""
        if len(self.train_rows) == 0:
            raise ValueError("the ranking dataset has no agent data yet")
        shape = (n_batches, batch_size)
        rows = self.train_rows[rng.integers(0, len(self.train_rows), size=shape)]
        experts = rng.integers(0, len(self.expert), size=shape)
        group = rng.integers(0, len(self.lambdas), size=shape)
        expert_steps = self._expert_steps(rng, rows[..., 1])
        inputs = self._mix(rows[..., 0], rows[..., 1], experts, expert_steps, group)
        return inputs, self.targets[group], (group == len(self.lambdas) - 1).astype(np.float32)

    def sample_interpolates(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> np.ndarray:
        """Random interpolations ``a + u (e - a)``, ``u ~ U(0, 1)``, of agent training rows and expert
        states from uniformly drawn trajectories and time steps: ``(n, B, d)``, the points of a
        gradient penalty (Gulrajani et al. 2017)."""
        if len(self.train_rows) == 0:
            raise ValueError("the ranking dataset has no agent data yet")
        shape = (n_batches, batch_size)
        rows = self.train_rows[rng.integers(0, len(self.train_rows), size=shape)]
        a = self.agent[rows[..., 0], rows[..., 1]]
        e = self.expert[rng.integers(0, len(self.expert), size=shape), rng.integers(0, self.horizon, size=shape)]
        return a + rng.uniform(size=(*shape, 1)).astype(np.float32) * (e - a)

    def holdout(self, max_rows: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every mixture of the holdout rows: inputs ``(R G, d)``, targets ``(R G,)``, is-expert ``(R G,)``.

        ``max_rows`` keeps an evenly strided subset of at most that many rows (the same subset each time
        the data is unchanged).
        """
        n_groups = len(self.lambdas)
        held = self.holdout_rows
        if max_rows is not None and len(held) > max_rows:
            held = held[np.linspace(0, len(held) - 1, max_rows).astype(np.int64)]
        rows = np.repeat(held, n_groups, axis=0)
        group = np.tile(np.arange(n_groups), len(held))
        inputs = self._mix(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], group)
        return inputs, self.targets[group], (group == n_groups - 1).astype(np.float32)

    def state_dict(self) -> dict[str, np.ndarray]:
        """The agent data as arrays for a checkpoint: ``ranking/agent (N, H, d)``, ``ranking/train_rows
        (R, 2)`` of ``(i, t)``, ``ranking/holdout_rows (R_h, 4)`` of ``(i, t, j, expert step)`` and the
        real-state count."""
        return {
            "ranking/n_real_states": np.asarray(self.n_real_states),
            "ranking/agent": self.agent,
            "ranking/train_rows": self.train_rows,
            "ranking/holdout_rows": self.holdout_rows,
        }

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`state_dict` (the expert data, grid and targets come from the constructor)."""
        self.agent = state["ranking/agent"]
        self.train_rows = state["ranking/train_rows"]
        self.holdout_rows = state["ranking/holdout_rows"]
        self.n_real_states = int(state["ranking/n_real_states"])
