"""What the reward reads: LfO ``r(s)`` or ``r(s, s')``, LfD ``r(s, a)``, built from episodes and SAC batches.

Every state in a reward input is a flagged observation (:mod:`rankgame.absorbing`), so a reward input
of kind ``s`` is ``[obs, flag]``, ``ss`` is ``[obs, flag, next_obs, next_flag]`` and ``sa`` is
``[obs, flag, act]`` with the action in SAC's normalized box ``[-1, 1]``. :class:`InputLayout` is the
one place that knows this layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import jax
import jax.numpy as jnp
import numpy as np

from rankgame.absorbing import absorbing_flag, padded_states

RewardInput = Literal["s", "ss", "sa"]


@dataclass(frozen=True)
class InputLayout:
    """Reward inputs of kind ``kind`` for a task with ``obs_dim`` observation and ``act_dim`` action entries."""

    obs_dim: int
    act_dim: int
    kind: RewardInput

    @property
    def dim(self) -> int:
        """Size ``d`` of one reward input, absorbing flags included."""
        flagged = self.obs_dim + 1
        return {"s": flagged, "ss": 2 * flagged, "sa": flagged + self.act_dim}[self.kind]

    def is_real(self, inputs: np.ndarray) -> np.ndarray:
        """Whether each input ``(..., d)`` starts in a real state, not the absorbing state: ``(...)`` bool."""
        return absorbing_flag(inputs[..., : self.obs_dim + 1]) == 0.0

    def episode(self, obs: np.ndarray, acts_norm: np.ndarray, terminated: bool, horizon: int) -> np.ndarray:
        """Reward inputs ``(H, d)`` float32 of one episode, padded with the absorbing state to the horizon.

        Args:
            obs: ``(T + 1, obs_dim)`` observations without flag.
            acts_norm: ``(T, act_dim)`` actions in the normalized box ``[-1, 1]`` (zero after the end).
            terminated: whether the episode ended in a true terminal state (else a time limit).
            horizon: H; an episode longer than H is cut to its first H steps.
        """
        padded = padded_states(obs, terminated, horizon)
        if self.kind == "s":
            return padded[:horizon]
        if self.kind == "ss":
            return np.concatenate([padded[:horizon], padded[1:]], axis=-1)
        length = min(len(acts_norm), horizon)
        acts = np.zeros((horizon, self.act_dim), np.float32)
        acts[:length] = acts_norm[:length]
        return np.concatenate([padded[:horizon], acts], axis=-1)

    def held_still(self, inputs: np.ndarray) -> np.ndarray:
        """Reward inputs ``(..., d)`` of staying one step in the state each input ``(..., d)`` starts in:
        the state itself, the self-transition ``(s, s)``, or ``(s, 0)``, the action at the middle of the
        normalized box (zero torque on the MuJoCo tasks)."""
        state = inputs[..., : self.obs_dim + 1].astype(np.float32)
        if self.kind == "ss":
            return np.concatenate([state, state], axis=-1)
        if self.kind == "sa":
            return np.concatenate([state, np.zeros((*state.shape[:-1], self.act_dim), np.float32)], axis=-1)
        return state

    def standing_still(self, first: np.ndarray, horizon: int) -> np.ndarray:
        """Reward inputs ``(n, H, d)`` of staying for ``horizon`` steps in the first state of each input
        ``first (n, d)`` (:meth:`held_still`)."""
        return np.repeat(self.held_still(first)[:, None], horizon, axis=1)

    def from_batch(self, batch: dict[str, jax.Array]) -> jax.Array:
        """Reward inputs ``(B, d)`` of a SAC batch (whose observations carry the absorbing flag)."""
        if self.kind == "s":
            return batch["obs"]
        if self.kind == "ss":
            return jnp.concatenate([batch["obs"], batch["next_obs"]], axis=-1)
        return jnp.concatenate([batch["obs"], batch["acts"]], axis=-1)

    def columns(self, obs_columns: Sequence[int]) -> tuple[int, ...] | None:
        """Entries of a reward input that belong to the observation entries ``obs_columns``: those
        entries and the absorbing flag of each state, and all actions; None when that is every entry."""
        if tuple(obs_columns) == tuple(range(self.obs_dim)):
            return None
        flagged = [*obs_columns, self.obs_dim]
        if self.kind == "s":
            return tuple(flagged)
        if self.kind == "ss":
            return (*flagged, *(c + self.obs_dim + 1 for c in flagged))
        return (*flagged, *range(self.obs_dim + 1, self.obs_dim + 1 + self.act_dim))


def parse_obs_columns(spec: str, obs_dim: int) -> tuple[int, ...]:
    """Observation entries named by ``spec``: ``all``, or indices and half-open ranges such as
    ``0:27`` or ``0:13,20:27``. Raises ``ValueError`` with a one-line reason for a bad spec."""
    if spec.strip() == "all":
        return tuple(range(obs_dim))
    columns: list[int] = []
    for item in spec.replace(",", " ").split():
        try:
            bounds = [int(part) for part in item.split(":")]
        except ValueError:
            bounds = []
        if not 1 <= len(bounds) <= 2:
            raise ValueError(f"{item!r} is neither an index nor a range like 0:27")
        start, stop = (bounds[0], bounds[0] + 1) if len(bounds) == 1 else bounds
        if not 0 <= start < stop <= obs_dim:
            raise ValueError(f"{item!r} is not a non-empty range inside the {obs_dim} observation entries")
        columns.extend(range(start, stop))
    if not columns or len(set(columns)) != len(columns):
        raise ValueError(f"{spec!r} must name each observation entry at most once, and at least one")
    return tuple(columns)
