"""A method is a combination of three named pieces (Sec. 4): ranking source x ranking loss x leader.

=================  =========  ==========  ======
method             rankings   loss        leader
=================  =========  ==========  ======
rank-pal-auto      auto       regression  pal
rank-ral-auto      auto       regression  ral
rank-pal-vanilla   vanilla    regression  pal
rank-ral-vanilla   vanilla    regression  ral
rank-pal-pref      pref       regression  pal
rank-ral-pref      pref       regression  ral
imit-pal           vanilla    supremum    pal
imit-ral           vanilla    supremum    ral
=================  =========  ==========  ======

Each column names an entry of one module: rankings in :mod:`rankgame.game.rankings` (``vanilla`` ranks
the agent below the expert; ``auto`` adds the time-aligned mixtures between them, App. B.1; ``pref``
adds a fixed chain of offline trajectories ranked below the expert, Eq. 6), losses in
:data:`rankgame.reward.losses.LOSSES`, leaders in :mod:`rankgame.game.leaders`. Adding a method means
adding a row to :data:`METHODS`, not another training loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from rankgame.game.leaders import LeaderName
from rankgame.game.rankings import RankingSource

LossName = Literal["regression", "supremum"]


@dataclass(frozen=True)
class Method:
    """Where rankings come from, which loss fits them, and which player leads."""

    rankings: RankingSource
    loss: LossName
    leader: LeaderName


METHODS: dict[str, Method] = {
    "rank-pal-auto": Method("auto", "regression", "pal"),
    "rank-ral-auto": Method("auto", "regression", "ral"),
    "rank-pal-vanilla": Method("vanilla", "regression", "pal"),
    "rank-ral-vanilla": Method("vanilla", "regression", "ral"),
    "rank-pal-pref": Method("pref", "regression", "pal"),
    "rank-ral-pref": Method("pref", "regression", "ral"),
    "imit-pal": Method("vanilla", "supremum", "pal"),
    "imit-ral": Method("vanilla", "supremum", "ral"),
}
