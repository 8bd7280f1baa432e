"""Replay buffer of transitions ``(obs, acts, next_obs, dones)``, deliberately without learned rewards.

Rewards are assigned when a batch is used (see :mod:`rankgame.policy.sac`), so a reward that keeps
learning never leaves stale labels behind. Extra per-transition fields (the environment's reward for
expert training, for instance) can be declared with ``extras``.
"""

from __future__ import annotations

import numpy as np


class ReplayBuffer:
    """Fixed-capacity ring buffer of float32 arrays in host memory.

    Args:
        capacity: number of transitions kept; the oldest are overwritten.
        obs_dim, act_dim: sizes of one observation and one action.
        extras: names of additional scalar fields stored per transition.
    """

    def __init__(self, capacity: int, obs_dim: int, act_dim: int, extras: tuple[str, ...] = ()) -> None:
        if capacity <= 0:
            raise ValueError("buffer capacity must be positive")
        self.capacity = capacity
        shapes = {"obs": (obs_dim,), "acts": (act_dim,), "next_obs": (obs_dim,), "dones": ()}
        shapes.update({name: () for name in extras})
        self.data = {name: np.zeros((capacity, *shape), np.float32) for name, shape in shapes.items()}
        self.size = 0
        self.pos = 0

    def __len__(self) -> int:
        return self.size

    def add(self, **transition: np.ndarray | float) -> None:
        """Store one transition; keyword names must match the buffer's fields exactly."""
        if transition.keys() != self.data.keys():
            raise KeyError(f"transition fields {sorted(transition)} != buffer fields {sorted(self.data)}")
        for name, value in transition.items():
            self.data[name][self.pos] = value
        self.pos = (self.pos + 1) % self.capacity
        self.size = min(self.size + 1, self.capacity)

    def sample(self, rng: np.random.Generator, n_batches: int, batch_size: int) -> dict[str, np.ndarray]:
        """Uniformly sample ``n_batches`` batches at once: arrays of shape ``(n_batches, batch_size, ...)``."""
        if self.size == 0:
            raise ValueError("cannot sample from an empty buffer")
        idx = rng.integers(0, self.size, size=(n_batches, batch_size))
        return {name: array[idx] for name, array in self.data.items()}

    def state_dict(self) -> dict[str, np.ndarray]:
        """Arrays that restore the buffer exactly (only the filled part is kept)."""
        out = {f"buffer/{name}": array[: self.size] for name, array in self.data.items()}
        out["buffer/pos"] = np.asarray(self.pos)
        return out

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`state_dict`."""
        size = int(state["buffer/obs"].shape[0])
        if size > self.capacity:
            raise ValueError(f"saved buffer holds {size} transitions, more than the capacity {self.capacity}")
        for name, array in self.data.items():
            array[:size] = state[f"buffer/{name}"]
        self.size = size
        self.pos = int(state["buffer/pos"])


def mix_demonstrations(
    batches: dict[str, np.ndarray], demonstrations: dict[str, np.ndarray], rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Half agent, half expert batches: each of the ``n`` sampled agent batches ``(n, B, ...)`` gets ``B``
    demonstration transitions drawn uniformly with replacement appended, and an ``is_expert`` field
    ``(n, 2B)`` that is 0 on the agent rows and 1 on the expert rows (IQ-Learn's batches).

    ``demonstrations`` holds arrays ``(N, ...)`` with the same fields as the batches (extra fields of the
    batches are not allowed: the expert rows would have no value for them), except that ``acts`` may be
    missing (observations only): each expert row then takes the action of the agent row in the same
    position, as IQ-Learn's authors do with ``only_expert_states``.
    """
    if set(batches) - {"acts"} != set(demonstrations) - {"acts"} or not set(demonstrations) <= set(batches):
        raise KeyError(f"demonstration fields {sorted(demonstrations)} != batch fields {sorted(batches)}")
    n, batch_size = batches["obs"].shape[:2]
    idx = rng.integers(0, len(demonstrations["obs"]), size=(n, batch_size))
    expert = {name: demonstrations[name][idx] if name in demonstrations else batches[name] for name in batches}
    mixed = {name: np.concatenate([batch, expert[name]], axis=1) for name, batch in batches.items()}
    flags = np.concatenate([np.zeros(batch_size, np.float32), np.ones(batch_size, np.float32)])
    mixed["is_expert"] = np.broadcast_to(flags, (n, 2 * batch_size)).copy()
    return mixed
