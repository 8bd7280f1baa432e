"""Replay buffer: storage, wrap-around, sampling shapes, round trip."""

from __future__ import annotations

import numpy as np
import pytest

from rankgame.policy.buffer import ReplayBuffer


def _fill(buffer: ReplayBuffer, n: int) -> None:
    for i in range(n):
        buffer.add(obs=np.full(2, i), acts=np.full(1, -i), next_obs=np.full(2, i + 1), dones=float(i % 2))


def test_buffer_wraps_around_and_keeps_the_newest() -> None:
    buffer = ReplayBuffer(4, obs_dim=2, act_dim=1)
    _fill(buffer, 6)
    assert len(buffer) == 4 and buffer.pos == 2
    assert sorted(buffer.data["obs"][:, 0].tolist()) == [2, 3, 4, 5]


def test_sample_shapes_and_consistency() -> None:
    buffer = ReplayBuffer(100, obs_dim=2, act_dim=1)
    _fill(buffer, 10)
    batch = buffer.sample(np.random.default_rng(0), n_batches=3, batch_size=5)
    assert batch["obs"].shape == (3, 5, 2) and batch["acts"].shape == (3, 5, 1) and batch["dones"].shape == (3, 5)
    np.testing.assert_array_equal(batch["next_obs"], batch["obs"] + 1)
    np.testing.assert_array_equal(batch["acts"][..., 0], -batch["obs"][..., 0])
    assert batch["obs"].max() <= 9  # only filled slots are drawn


def test_buffer_has_no_reward_unless_asked() -> None:
    assert "rews" not in ReplayBuffer(4, 2, 1).data
    assert "rews" in ReplayBuffer(4, 2, 1, extras=("rews",)).data


def test_wrong_fields_are_rejected() -> None:
    buffer = ReplayBuffer(4, 2, 1)
    with pytest.raises(KeyError, match="fields"):
        buffer.add(obs=np.zeros(2), acts=np.zeros(1), next_obs=np.zeros(2), dones=0.0, rews=1.0)
    with pytest.raises(ValueError, match="empty"):
        buffer.sample(np.random.default_rng(0), 1, 1)


def test_state_dict_round_trip() -> None:
    buffer = ReplayBuffer(8, 2, 1)
    _fill(buffer, 5)
    restored = ReplayBuffer(8, 2, 1)
    restored.load_state_dict(buffer.state_dict())
    assert len(restored) == 5 and restored.pos == buffer.pos
    for name in buffer.data:
        np.testing.assert_array_equal(restored.data[name][:5], buffer.data[name][:5])
