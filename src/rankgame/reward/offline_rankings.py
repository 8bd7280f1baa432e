"""Offline rankings ``rho^1 <= ... <= rho^p <= rho^E`` for the (pref) methods (Eq. 6, App. B.1 and B.3).

The ``p`` offline trajectories, ordered worst to best and grounded by the expert, form a chain of
``p + 1`` behaviors. Behavior ``i`` is regressed to the target ``k_i`` of the same schedule the auto
mixtures use, at ``i / p`` of the way from the bottom of the chain to the expert (the shaped loss
SL_k, Eq. 8, with offline trajectories in place of mixtures). As in App. B.3, every sampled snippet
of ``l`` consecutive steps is also regressed: its summed reward to ``k_i l``. The snippet term is
divided by ``l^2``, so that it is the squared error of the snippet's *mean* reward and lies on the
same scale as the per-state term.

Noisy rankings (App. D, robustness to noisy preferences, which flips a share of snippet comparisons)
are simulated with ``noise``: that share of the offline trajectories' state and snippet labels is
replaced, once and for the whole run, by the rank of another offline trajectory drawn uniformly.
The expert's labels stay: it grounds the chain.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class OfflineRankings:
    """A fixed chain of ranked trajectories, sampled as states and as snippets.

    Args:
        ranked: ``(p, H, d)`` reward inputs of the offline trajectories, worst first, padded with
            absorbing states to the horizon like agent data.
        expert: ``(M, H, d)`` expert reward inputs, the top of the chain.
        targets: ``(p + 1,)`` non-decreasing regression targets, the expert's last.
        snippet_length: ``l``, steps per snippet (at most H).
        noise: share of offline labels given another trajectory's rank, in ``[0, 1]``.
        noise_seed: seed (or seed sequence) of which labels are corrupted and how.
    """

    def __init__(
        self,
        ranked: np.ndarray,
        expert: np.ndarray,
        targets: np.ndarray,
        snippet_length: int,
        noise: float = 0.0,
        noise_seed: int | Sequence[int] = 0,
    ) -> None:
        if ranked.ndim != 3 or len(ranked) < 1 or expert.ndim != 3 or ranked.shape[1:] != expert.shape[1:]:
            raise ValueError(
                f"offline inputs {ranked.shape} and expert inputs {expert.shape} must both be (n, H, d), n >= 1"
            )
        if targets.shape != (len(ranked) + 1,) or np.any(np.diff(targets) < 0):
            raise ValueError("offline rankings need one non-decreasing target per trajectory plus the expert's")
        if not 1 <= snippet_length <= ranked.shape[1]:
            raise ValueError(f"the snippet length must lie in [1, {ranked.shape[1]}] (the horizon)")
        if not 0.0 <= noise <= 1.0 or (noise > 0.0 and len(ranked) < 2):
            raise ValueError("the preference noise must lie in [0, 1], and needs at least 2 offline trajectories")
        # Offline trajectories first, then the expert's: one store, so a batch is one gather.
        self.trajectories = np.concatenate([ranked, expert]).astype(np.float32)
        self.ranked, self.expert = self.trajectories[: len(ranked)], self.trajectories[len(ranked) :]
        self.targets = targets.astype(np.float32)
        self.snippet_length = snippet_length
        self.horizon = ranked.shape[1]
        noise_rng = np.random.default_rng(noise_seed)
        # The rank each behavior's state at time t, and its snippet starting at t, is labelled with.
        self.state_rank = self._noisy_ranks(noise_rng, self.horizon, noise)
        self.snippet_rank = self._noisy_ranks(noise_rng, self.horizon - snippet_length + 1, noise)

    def _noisy_ranks(self, rng: np.random.Generator, n_positions: int, noise: float) -> np.ndarray:
        """Labels ``(p + 1, n_positions)``: behavior b's own rank, except that a ``noise`` share of the offline
        rows' entries hold a uniformly drawn other offline rank."""
        p = len(self.ranked)
        ranks = np.repeat(np.arange(p + 1)[:, None], n_positions, axis=1)
        flipped = rng.uniform(size=(p, n_positions)) < noise
        other = (ranks[:p] + rng.integers(1, max(p, 2), size=(p, n_positions))) % p  # never the own rank
        ranks[:p] = np.where(flipped, other, ranks[:p])
        return ranks

    @property
    def n_behaviors(self) -> int:
        """``p + 1``: the offline trajectories and the expert."""
        return len(self.ranked) + 1

    def sample(
        self, rng: np.random.Generator, n_batches: int, batch_size: int
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Training batches, every behavior equally likely.

        Returns:
            states ``(n, B, d)`` and their targets ``(n, B)``; snippets ``(n, S, l, d)`` and their
            per-step targets ``(n, S)``, with ``S = max(1, B // l)`` snippets per batch.
        """
        shape = (n_batches, batch_size)
        behavior = rng.integers(0, self.n_behaviors, size=shape)
        t = rng.integers(0, self.horizon, size=shape)
        states = self._states(rng, behavior, t)
        n_snippets = max(1, batch_size // self.snippet_length)
        snippet_behavior = rng.integers(0, self.n_behaviors, size=(n_batches, n_snippets))
        start = rng.integers(0, self.horizon - self.snippet_length + 1, size=(n_batches, n_snippets))
        steps = start[..., None] + np.arange(self.snippet_length)
        snippets = self._states(rng, np.repeat(snippet_behavior[..., None], self.snippet_length, axis=-1), steps)
        state_targets = self.targets[self.state_rank[behavior, t]]
        return states, state_targets, snippets, self.targets[self.snippet_rank[snippet_behavior, start]]

    def sample_pairs(self, rng: np.random.Generator, n_batches: int, n_pairs: int) -> tuple[np.ndarray, np.ndarray]:
        """Pairs of snippets of two different behaviors of the chain, for a pairwise loss (T-REX).

        Each pair draws two distinct behaviors uniformly and one snippet of ``l`` steps from each; as in
        T-REX (Brown et al. 2019, App. A) the better behavior's snippet starts no earlier than the
        worse one's, so that it is not preferred only for being further along. With preference noise,
        the order of a pair follows the noisy labels of its snippets' starts.

        Returns:
            the better snippets ``(n, S, l, d)`` and the worse ones ``(n, S, l, d)``, S = ``n_pairs``.
        """
        shape = (n_batches, n_pairs)
        first = rng.integers(0, self.n_behaviors, size=shape)
        second = (first + rng.integers(1, self.n_behaviors, size=shape)) % self.n_behaviors
        worse, better = np.minimum(first, second), np.maximum(first, second)
        n_starts = self.horizon - self.snippet_length + 1
        start_worse = rng.integers(0, n_starts, size=shape)
        start_better = start_worse + (rng.uniform(size=shape) * (n_starts - start_worse)).astype(np.int64)
        flip = self.snippet_rank[better, start_better] < self.snippet_rank[worse, start_worse]
        steps = np.arange(self.snippet_length)

        def snippets(behavior: np.ndarray, start: np.ndarray) -> np.ndarray:
            length = self.snippet_length
            return self._states(rng, np.repeat(behavior[..., None], length, axis=-1), start[..., None] + steps)

        b, w = snippets(better, start_better), snippets(worse, start_worse)
        return np.where(flip[..., None, None], w, b), np.where(flip[..., None, None], b, w)

    def _states(self, rng: np.random.Generator, behavior: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Inputs ``(n, B, [l,] d)`` at times ``t`` of behaviors ``behavior`` (both ``(n, B[, l])``).

        An expert behavior reads one uniformly drawn expert trajectory per ``(n, B)`` entry, so a
        snippet stays within one trajectory.
        """
        p = len(self.ranked)
        expert_pick = rng.integers(0, len(self.expert), size=behavior.shape[:2])
        expert_pick = expert_pick.reshape(expert_pick.shape + (1,) * (behavior.ndim - 2))
        return self.trajectories[np.where(behavior == p, p + expert_pick, behavior), t]
