"""Regression targets k_0 <= ... <= k_{P+1} for the shaped ranking loss SL_k (App. B.1).

A mixture ``lambda`` of the way from the agent (``lambda = 0``) to the expert (``lambda = 1``) is
regressed to ``k(lambda)`` with ``k(0) = low`` and ``k(1) = high`` (the paper's ``[0, k]``):

* ``linear``: ``k(lambda) = low + (high - low) lambda``;
* ``exp`` with temperature ``beta`` (``dk/dlambda`` proportional to ``e^{beta lambda}``):
  ``k(lambda) = low + (high - low) (e^{beta lambda} - 1) / (e^{beta} - 1)``; ``beta < 0`` puts the
  larger gaps near the agent. ``beta = 0`` is the linear schedule.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

Schedule = Literal["linear", "exp"]


def target_schedule(
    lambdas: np.ndarray, low: float, high: float, schedule: Schedule = "exp", beta: float = -1.0
) -> np.ndarray:
    """Targets ``(P + 2,)`` (float64) for mixture weights ``lambdas (P + 2,)`` in ``[0, 1]``."""
    lambdas = np.asarray(lambdas, np.float64)
    if np.any(lambdas < 0.0) or np.any(lambdas > 1.0):
        raise ValueError("mixture weights must lie in [0, 1]")
    if schedule == "linear" or (schedule == "exp" and abs(beta) < 1e-12):
        frac = lambdas
    elif schedule == "exp" and beta < 0:
        frac = np.expm1(beta * lambdas) / np.expm1(beta)
    elif schedule == "exp":  # the same fraction, written so that a large beta cannot overflow
        frac = np.exp(beta * (lambdas - 1.0)) * np.expm1(-beta * lambdas) / np.expm1(-beta)
    else:
        raise ValueError(f"unknown target schedule {schedule!r}; choose linear or exp")
    return low + (high - low) * frac


def lambda_grid(n_interpolations: int) -> np.ndarray:
    """Evenly spaced mixture weights ``(n_interpolations + 2,)`` from 0 to 1, both ends included.

    The default, 4 interior mixtures, gives ``0, 0.2, ..., 1``: five equal steps from the agent to the
    expert. This is the grid of the authors' code; we read Table 4's "5 interpolations" as these five
    steps, while App. B's notation would count the P interior mixtures (4 here).
    """
    if n_interpolations < 0:
        raise ValueError("the number of interpolations must be >= 0")
    return np.linspace(0.0, 1.0, n_interpolations + 2)
