"""The policy player's reward averaged over the reward player's last rewards (rankgame.reward.averaging)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.reward.averaging import RewardAverage


def _linear(params: dict[str, jnp.ndarray], batch: dict[str, jnp.ndarray]) -> jnp.ndarray:
    """r(x) = w * x + b for scalar states ``(B, 1)``."""
    return batch["obs"][:, 0] * params["w"] + params["b"]


def _params(w: float, b: float) -> dict[str, jnp.ndarray]:
    return {"w": jnp.float32(w), "b": jnp.float32(b)}


BATCH = {"obs": jnp.asarray([[0.0], [1.0], [2.0]])}


def test_a_window_of_three_pays_the_mean_of_the_last_three_rewards() -> None:
    average = RewardAverage(_linear, 3)
    window = average.start(_params(100.0, 100.0))  # the reward at initialization, until the first turn
    np.testing.assert_allclose(average.reward_fn(window, BATCH), [100.0, 200.0, 300.0])
    window = average.push(window, _params(1.0, 0.0))  # the first fit replaces it: r = x
    np.testing.assert_allclose(average.reward_fn(window, BATCH), [0.0, 1.0, 2.0])
    window = average.push(window, _params(2.0, 0.0))  # mean of x and 2x: 1.5x
    np.testing.assert_allclose(average.reward_fn(window, BATCH), [0.0, 1.5, 3.0])
    window = average.push(window, _params(0.0, 3.0))  # (x + 2x + 3) / 3 = x + 1
    np.testing.assert_allclose(average.reward_fn(window, BATCH), [1.0, 2.0, 3.0], rtol=1e-6)
    window = average.push(window, _params(-3.0, 6.0))  # x is dropped: (2x + 3 - 3x + 6) / 3 = 3 - x / 3
    np.testing.assert_allclose(average.reward_fn(window, BATCH), [3.0, 3.0 - 1 / 3, 3.0 - 2 / 3], rtol=1e-6)
    assert int(window.count) == 4


def test_a_window_of_one_hands_the_latest_reward_through_unchanged() -> None:
    average = RewardAverage(_linear, 1)
    latest = _params(2.0, 1.0)
    assert average.reward_fn is _linear
    assert average.start(_params(0.0, 0.0)) is not latest
    assert average.push(average.start(_params(0.0, 0.0)), latest) is latest
    assert average.state_dict(latest) == {}


def test_a_window_restores_from_its_checkpoint_arrays() -> None:
    average = RewardAverage(_linear, 2)
    window = average.push(average.push(average.start(_params(0.0, 0.0)), _params(1.0, 0.0)), _params(0.0, 5.0))
    restored = average.load(average.state_dict(window), average.start(_params(9.0, 9.0)), _params(9.0, 9.0))
    assert int(restored.count) == 2
    np.testing.assert_array_equal(average.reward_fn(restored, BATCH), average.reward_fn(window, BATCH))


def test_an_empty_window_is_refused() -> None:
    with pytest.raises(ValueError, match="at least 1 reward"):
        RewardAverage(_linear, 0)
