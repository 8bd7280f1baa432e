"""The SL_k rank-preservation study (benchmarks/rank_preservation.py): its closed-form minimizer against
the package's regression loss, cases worked out by hand, and the script's errors."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rankgame.reward.losses import regression_ranking_loss

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import rank_preservation  # noqa: E402


def test_two_states_two_behaviors_by_hand() -> None:
    # R*(s0) = (0.75 * 0 + 0.25 * 10) / 1 = 2.5, R*(s1) = (0.25 * 0 + 0.75 * 10) / 1 = 7.5;
    # E_rho0 R* = 0.75 * 2.5 + 0.25 * 7.5 = 3.75 < E_rho1 R* = 6.25.
    rho = np.array([[0.75, 0.25], [0.25, 0.75]])
    reward = rank_preservation.sl_k_minimizer(rho, np.array([0.0, 10.0]))
    np.testing.assert_allclose(reward, [2.5, 7.5])
    assert rank_preservation.rank_consistency(rho, reward) == 1.0


def test_a_ranking_the_minimizer_breaks_by_hand() -> None:
    # rho = (0, 1), (1, 0), (1/2, 1/2) with targets 0, 5, 10: R*(s0) = (5 + 5) / 1.5 = 20/3 and
    # R*(s1) = (0 + 5) / 1.5 = 10/3, so the returns are 10/3, 20/3 and 5: the pair (1, 2) is reversed.
    rho = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]])
    reward = rank_preservation.sl_k_minimizer(rho, np.array([0.0, 5.0, 10.0]))
    np.testing.assert_allclose(reward, [20 / 3, 10 / 3])
    assert rank_preservation.rank_consistency(rho, reward) == pytest.approx(2 / 3)


def test_the_closed_form_is_where_the_packages_regression_loss_is_smallest() -> None:
    """Each (behavior, state) pair is one input of the package's SL_k, weighted by rho_i(s): that is the
    expectation of Eq. 8 over behaviors drawn uniformly. Its gradient vanishes at the closed form, and
    moving away from it raises the loss."""
    rng = np.random.default_rng(3)
    n, size = 4, 6
    rho = rng.dirichlet(np.ones(size), size=n)
    targets = np.sort(rng.uniform(0, 10, size=n))
    behavior, state = np.meshgrid(np.arange(n), np.arange(size), indexing="ij")

    def loss(table: jax.Array) -> jax.Array:
        raw = table[state.ravel()]
        return regression_ranking_loss(raw, jnp.asarray(targets[behavior.ravel()]), jnp.asarray(rho.ravel()))[0]

    best = jnp.asarray(rank_preservation.sl_k_minimizer(rho, targets))
    np.testing.assert_allclose(jax.grad(loss)(best), 0.0, atol=1e-5)
    for _ in range(5):
        assert loss(best + 0.1 * jnp.asarray(rng.normal(size=size))) > loss(best)


def test_two_behaviors_are_always_kept() -> None:
    """E_rho1 R* - E_rho0 R* = (k1 - k0) sum_s (rho1 - rho0)^2 / (2 (rho0 + rho1)) >= 0 for n = 2."""
    rng = np.random.default_rng(0)
    rho = rng.dirichlet(np.ones(7), size=(500, 2))
    targets = rank_preservation.draw_targets(rng, 500, 2, "uniform", 10.0)
    assert np.all(rank_preservation.rank_consistency(rho, rank_preservation.sl_k_minimizer(rho, targets)) == 1.0)


def test_uniform_targets_are_sorted_and_pinned_to_zero_and_k() -> None:
    targets = rank_preservation.draw_targets(np.random.default_rng(1), 100, 5, "uniform", 4.0)
    assert targets.shape == (100, 5)
    assert np.all(np.diff(targets, axis=1) >= 0) and np.all(targets[:, 0] == 0) and np.all(targets[:, -1] == 4.0)
    exp = rank_preservation.draw_targets(np.random.default_rng(1), 3, 3, "exp", 10.0)
    # The default exp schedule (beta = -1) at lambda = 1/2: 10 (e^-0.5 - 1) / (e^-1 - 1).
    np.testing.assert_allclose(exp[:, 1], 10 * np.expm1(-0.5) / np.expm1(-1.0))


def test_more_states_keep_more_pairs_and_more_behaviors_fewer(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--states", "3", "300", "--behaviors", "3", "8", "--trials", "300"]
    assert rank_preservation.main(argv) == 0
    cells = {(c["states"], c["behaviors"]): c for c in json.loads(capsys.readouterr().out)["cells"]}
    consistency = {key: cell["mean_consistency"] for key, cell in cells.items()}
    assert consistency[(300, 3)] > consistency[(3, 3)] + 0.05 and consistency[(300, 8)] > consistency[(3, 8)] + 0.05
    assert consistency[(3, 3)] > consistency[(3, 8)] + 0.05
    assert cells[(3, 8)]["pairs"] == 28 and cells[(3, 8)]["ci95"][0] <= consistency[(3, 8)] <= cells[(3, 8)]["ci95"][1]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--behaviors", "1"], "--behaviors must be at least 2 (one pair)"),
        (["--states", "0"], "--states must be positive"),
        (["--k", "nan"], "--k must be positive and finite"),
    ],
)
def test_settings_that_make_no_sense_are_one_line_errors(
    argv: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert rank_preservation.main(argv) == 1
    assert capsys.readouterr().err == f"rank_preservation.py: {message}\n"
