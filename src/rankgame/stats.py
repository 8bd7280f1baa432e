"""Aggregate statistics over runs and tasks, as reliable RL evaluation reports them (pure NumPy).

After Agarwal et al. 2021, "Deep Reinforcement Learning at the Edge of the Statistical Precipice"
(the ``rliable`` library), written here without it:

* :func:`iqm`: the interquartile mean, the mean of the middle 50% of the runs' scores;
* :func:`stratified_bootstrap_ci`: a percentile confidence interval of any statistic of per-task run
  scores, resampling runs with replacement within each task (the stratified bootstrap);
* :func:`probability_of_improvement`: the chance that a run of one method beats a run of another on
  a task, averaged over tasks, with a stratified-bootstrap interval;
* :func:`performance_profile`: the fraction of runs that score above each threshold;
* :func:`mean_and_sample_std`: the mean and the ``n - 1`` standard deviation of a few seeds.

Shapes: ``n`` runs of one task, ``T`` tasks, ``B`` bootstrap samples, ``K`` thresholds. Per-task
scores are a sequence of ``T`` one-dimensional arrays, ``(n_t,)`` each; tasks may have different
numbers of runs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

#: A statistic of per-task scores: ``T`` arrays, ``(n_t,)`` each (or ``(B, n_t)`` each, vectorized), to a
#: float (or ``(B,)``, vectorized).
Statistic = Callable[[Sequence[np.ndarray]], "float | np.ndarray"]


class Interval(NamedTuple):
    """A point estimate with the bounds of its confidence interval."""

    estimate: float
    low: float
    high: float


def _iqm_weights(n: int) -> np.ndarray:
    """Weights ``(n,)`` (summing to 1) of the sorted values in :func:`iqm`: the share of the middle half
    ``[1/4, 3/4]`` of the probability mass that each value's ``[i/n, (i+1)/n]`` covers."""
    edges = np.arange(n + 1) / n
    covered = np.clip(np.minimum(edges[1:], 0.75) - np.maximum(edges[:-1], 0.25), 0.0, None)
    return covered / covered.sum()


def iqm(scores: ArrayLike, axis: int | None = None) -> float | np.ndarray:
    """Interquartile mean: the mean of the middle 50% of ``scores``, 25% trimmed at each end.

    Definition (fractional weights): each of the ``n`` sorted values holds ``1/n`` of the probability
    mass, value ``i`` (from 0) the interval ``[i/n, (i+1)/n]``; the IQM is the mean of the values
    weighted by how much of ``[1/4, 3/4]`` each interval covers. So a value cut by a quartile counts
    in part: for ``n = 3`` the weights are ``1/6, 2/3, 1/6``, for ``n = 5`` ``0, 0.3, 0.4, 0.3, 0``, and
    ``n = 1`` or ``2`` give the plain mean. When ``n`` is a multiple of 4 this is exactly the mean of the
    middle ``n/2`` values, as ``scipy.stats.trim_mean(scores, 0.25)`` (rliable's IQM) gives; otherwise
    trim_mean drops ``floor(n/4)`` whole values at each end instead (for ``n = 3`` nothing: the mean).

    ``scores``: any shape; with ``axis=None`` all entries are pooled (rliable's IQM of a ``(runs, tasks)``
    score matrix) and a float is returned, with an ``axis`` the IQM along it (e.g. ``(B, n)`` with
    ``axis=-1`` gives ``(B,)``).
    """
    values = np.asarray(scores, np.float64)
    if axis is None:
        values, axis = values.reshape(-1), -1
    values = np.moveaxis(values, axis, -1)
    n = values.shape[-1]
    if n == 0:
        raise ValueError("iqm needs at least one score")
    result = np.sort(values, axis=-1) @ _iqm_weights(n)
    return float(result) if np.ndim(result) == 0 else result


def _resampled(strata: Sequence[np.ndarray], n_boot: int, rng: np.random.Generator) -> list[np.ndarray]:
    """``n_boot`` resamples of every stratum: for each ``(n_t,)`` array, a ``(B, n_t)`` array of its values
    drawn with replacement (each row one bootstrap sample of that stratum's runs)."""
    return [stratum[rng.integers(0, len(stratum), size=(n_boot, len(stratum)))] for stratum in strata]


def _strata(scores_by_task: Sequence[ArrayLike]) -> list[np.ndarray]:
    strata = [np.asarray(scores, np.float64).reshape(-1) for scores in scores_by_task]
    if not strata or any(len(stratum) == 0 for stratum in strata):
        raise ValueError("every task needs at least one run score")
    return strata


def _percentile_interval(estimate: float, samples: np.ndarray, level: float) -> Interval:
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")
    low, high = np.quantile(samples, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    return Interval(float(estimate), float(low), float(high))


def stratified_bootstrap_ci(
    scores_by_task: Sequence[ArrayLike],
    statistic: Statistic,
    n_boot: int = 2000,
    seed: int = 0,
    level: float = 0.95,
    vectorized: bool = False,
) -> Interval:
    """``statistic`` of the per-task scores with its stratified-bootstrap percentile interval.

    ``scores_by_task``: ``T`` arrays, ``(n_t,)`` each, the scores of task ``t``'s runs. Each of the
    ``n_boot`` bootstrap samples draws ``n_t`` runs with replacement within every task ``t`` (never across
    tasks); the interval is the ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles (linear
    interpolation) of the statistic over the samples, the estimate the statistic of the scores themselves.

    ``statistic`` takes ``T`` arrays, ``(n_t,)`` each, and returns a float; with ``vectorized`` it takes
    ``T`` arrays ``(B, n_t)`` (one row per sample) and returns ``(B,)``. For example the IQM of all runs
    pooled: ``lambda tasks: iqm(np.concatenate(tasks))``, vectorized
    ``lambda tasks: iqm(np.concatenate(tasks, axis=-1), axis=-1)``.
    """
    strata = _strata(scores_by_task)
    if n_boot < 1:
        raise ValueError(f"n_boot must be positive, got {n_boot}")
    rng = np.random.default_rng(seed)
    resampled = _resampled(strata, n_boot, rng)
    if vectorized:
        samples = np.asarray(statistic(resampled), np.float64).reshape(n_boot)
        estimate = float(np.asarray(statistic([s[None, :] for s in strata])).reshape(()))
    else:
        samples = np.array([statistic([r[b] for r in resampled]) for b in range(n_boot)], np.float64)
        estimate = float(statistic(strata))  # type: ignore[arg-type]
    return _percentile_interval(estimate, samples, level)


def _improvement(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """P(X > Y) + P(X = Y) / 2 over all pairs of a row of ``xs`` ``(..., n_x)`` and of ``ys`` ``(..., n_y)``:
    ``(...)``."""
    diff = xs[..., :, None] - ys[..., None, :]
    return ((diff > 0) + 0.5 * (diff == 0)).mean(axis=(-2, -1))


def probability_of_improvement(
    x_by_task: Sequence[ArrayLike],
    y_by_task: Sequence[ArrayLike],
    n_boot: int = 2000,
    seed: int = 0,
    level: float = 0.95,
) -> Interval:
    """Probability that method X improves on method Y, averaged over tasks, with a bootstrap interval.

    ``x_by_task`` and ``y_by_task``: ``T`` arrays each, the run scores ``(n_t,)`` of X and ``(m_t,)`` of Y
    on the same task ``t``. Per task the estimate is the Mann-Whitney form over all ``n_t * m_t`` pairs of
    runs, ``P(X > Y) + 0.5 P(X = Y)``; the result is its mean over tasks (0.5: no difference). The
    interval resamples X's and Y's runs independently, with replacement, within each task (a stratified
    bootstrap of both, as rliable does), and takes percentiles as :func:`stratified_bootstrap_ci`.
    """
    xs, ys = _strata(x_by_task), _strata(y_by_task)
    if len(xs) != len(ys):
        raise ValueError(f"X has {len(xs)} tasks and Y {len(ys)}; give both the same tasks")
    if n_boot < 1:
        raise ValueError(f"n_boot must be positive, got {n_boot}")
    estimate = float(np.mean([_improvement(x, y) for x, y in zip(xs, ys, strict=True)]))
    resampled = _resampled([*xs, *ys], n_boot, np.random.default_rng(seed))
    per_task = [_improvement(x, y) for x, y in zip(resampled[: len(xs)], resampled[len(xs) :], strict=True)]
    return _percentile_interval(estimate, np.mean(per_task, axis=0), level)


def performance_profile(scores: ArrayLike, thresholds: ArrayLike) -> np.ndarray:
    """Fraction of runs whose score is above (strictly) each threshold (rliable's score distribution).

    ``scores``: any shape, all entries pooled (``(n,)`` runs, or ``(runs, tasks)``); ``thresholds``:
    ``(K,)``. Returns ``(K,)``, non-increasing for increasing thresholds.
    """
    values = np.asarray(scores, np.float64).reshape(-1)
    if len(values) == 0:
        raise ValueError("performance_profile needs at least one score")
    taus = np.asarray(thresholds, np.float64).reshape(-1)
    return (values[None, :] > taus[:, None]).mean(axis=1)


def mean_and_sample_std(values: ArrayLike) -> tuple[float, float | None]:
    """Mean and sample standard deviation (``n - 1`` in the denominator) of ``values`` ``(n,)``; the
    standard deviation is None for ``n < 2``, which does not define it."""
    array = np.asarray(values, np.float64).reshape(-1)
    if len(array) == 0:
        raise ValueError("mean_and_sample_std needs at least one value")
    std = float(np.std(array, ddof=1)) if len(array) > 1 else None
    return float(np.mean(array)), std
