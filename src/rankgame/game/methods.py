"""A method is a combination of named pieces (Sec. 3-4): ranking source x ranking loss x leader, played
by a policy player in the settings the method allows.

=================  =========  =============  ============  ======  =========
method             rankings   loss           leader        policy  settings
=================  =========  =============  ============  ======  =========
rank-pal-auto      auto       regression     pal           sac     lfo, lfd
rank-ral-auto      auto       regression     ral           sac     lfo, lfd
rank-pal-vanilla   vanilla    regression     pal           sac     lfo, lfd
rank-ral-vanilla   vanilla    regression     ral           sac     lfo, lfd
rank-pal-pref      pref       regression     pal           sac     lfo, lfd
rank-ral-pref      pref       regression     ral           sac     lfo, lfd
imit-pal           vanilla    supremum       pal           sac     lfo, lfd
imit-ral           vanilla    supremum       ral           sac     lfo, lfd
gail               vanilla    logistic       gda           ppo     lfd
gaifo              vanilla    logistic       gda           ppo     lfo
dac                vanilla    logistic-gp    gda-replay    sac     lfd
dacfo              vanilla    logistic-gp    gda-replay    sac     lfo
trex               offline    bradley-terry  reward-first  sac     lfo, lfd
f-irl              marginal   f-divergence   gda           sac     lfo
opolo              vanilla    logistic-gp+   gda-replay    opolo   lfo
=================  =========  =============  ============  ======  =========

GAIfO, DACfO and OPOLO read state transitions ``(s, s')`` from observations, as in their papers; every
other method reads ``s``, and ``(s, a)`` from demonstrations. (``logistic-gp+`` stands for
``logistic-gp-softplus``.)

Each column names an entry of one module: rankings in :mod:`rankgame.game.rankings` (``vanilla`` ranks
the agent below the expert; ``auto`` adds the time-aligned mixtures between them, App. B.1; ``pref``
adds a fixed chain of offline trajectories ranked below the expert, Eq. 6; ``offline`` is that chain
alone, in pairs of snippets; ``marginal`` compares state marginals through a density ratio, f-IRL's),
losses in :data:`rankgame.reward.losses.LOSSES`, leaders in
:mod:`rankgame.game.leaders`, policy players in :mod:`rankgame.policy` (SAC, PPO). GAIL and GAIfO
(Ho & Ermon 2016; Torabi et al. 2018) and DAC and DACfO (Kostrikov et al. 2019) are the same
discriminator game in LfD and LfO; the IMIT methods are their Stackelberg counterparts (the paper,
Sec. 3); f-IRL (Ni et al. 2020) follows the gradient of an f-divergence between the state marginals;
OPOLO (Zhu et al. 2020) pays a TD3 policy player (:mod:`rankgame.policy.opolo`) GAIL's reward from a
discriminator on state transitions and trains it on the dual form of transition-marginal matching.
Adding a method means adding a row to :data:`METHODS`, not another training loop.

Behavior cloning plays no game: ``bc`` (LfD) and ``bco`` (LfO) are trainers of their own
(:mod:`rankgame.baselines`), and so is IQ-Learn (``iq-learn``, LfD), whose critic is its reward model;
they are listed in :data:`OWN_TRAINER_METHODS` with the settings they learn in.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from rankgame.game.leaders import LeaderName
from rankgame.game.rankings import RankingSource
from rankgame.reward.inputs import RewardInput

LossName = Literal[
    "regression", "supremum", "logistic", "logistic-gp", "bradley-terry", "f-divergence", "logistic-gp-softplus"
]
PolicyName = Literal["sac", "ppo", "opolo"]
Setting = Literal["lfo", "lfd"]


@dataclass(frozen=True)
class Method:
    """Where rankings come from, which loss fits them, which player leads, who plays the policy, and
    whether the expert's actions may (``lfd``) or need not (``lfo``) be used (the first is the default);
    ``lfo_input`` is the reward's input from observations: ``s`` (the paper's ``r(s)``) or ``ss``, the
    state transitions ``(s, s')`` of GAIfO, DACfO and OPOLO. ``reward_steps`` is the reward's gradient steps per
    iteration under a fixed-budget leader when the method sets them, and ``iteration_horizons`` an
    iteration's length in horizons when it is not the policy player's (both f-IRL's: 1 and 5)."""

    rankings: RankingSource
    loss: LossName
    leader: LeaderName
    policy: PolicyName = "sac"
    settings: tuple[Setting, ...] = ("lfo", "lfd")
    lfo_input: RewardInput = "s"
    reward_steps: int | None = None
    iteration_horizons: int | None = None

    @property
    def uses_preferences(self) -> bool:
        """Whether the rankings include a preference file's offline trajectories (pref, offline)."""
        return self.rankings in ("pref", "offline")


METHODS: dict[str, Method] = {
    "rank-pal-auto": Method("auto", "regression", "pal"),
    "rank-ral-auto": Method("auto", "regression", "ral"),
    "rank-pal-vanilla": Method("vanilla", "regression", "pal"),
    "rank-ral-vanilla": Method("vanilla", "regression", "ral"),
    "rank-pal-pref": Method("pref", "regression", "pal"),
    "rank-ral-pref": Method("pref", "regression", "ral"),
    "imit-pal": Method("vanilla", "supremum", "pal"),
    "imit-ral": Method("vanilla", "supremum", "ral"),
    "gail": Method("vanilla", "logistic", "gda", "ppo", ("lfd",)),
    "gaifo": Method("vanilla", "logistic", "gda", "ppo", ("lfo",), lfo_input="ss"),
    "dac": Method("vanilla", "logistic-gp", "gda-replay", "sac", ("lfd",)),
    "dacfo": Method("vanilla", "logistic-gp", "gda-replay", "sac", ("lfo",), lfo_input="ss"),
    "trex": Method("offline", "bradley-terry", "reward-first"),
    "f-irl": Method("marginal", "f-divergence", "gda", "sac", ("lfo",), reward_steps=1, iteration_horizons=5),
    # OPOLO's discriminator: the authors' 10 steps per 500 environment steps, 20 per horizon, rounded up to
    # whole fused calls of the reward player (8 steps each).
    "opolo": Method(
        "vanilla", "logistic-gp-softplus", "gda-replay", "opolo", ("lfo",), lfo_input="ss", reward_steps=24
    ),
}


@dataclass(frozen=True)
class OwnTrainer:
    """A method that plays no ranking game but has a trainer of its own (:mod:`rankgame.baselines`): the
    settings it learns in (the first is the default), the option groups it reads besides the run's own,
    its SAC preset (``--preset``'s default for it), if it has a SAC, and whether it acts in the
    environment (if not, its steps are gradient steps)."""

    settings: tuple[Setting, ...]
    groups: tuple[str, ...]
    sac_preset: str | None = None
    acts: bool = True


#: The methods with trainers of their own: behavior cloning (``bc``, ``bco``) and IQ-Learn, whose critic
#: is its reward model (:mod:`rankgame.baselines.iq`).
OWN_TRAINER_METHODS: dict[str, OwnTrainer] = {
    "bc": OwnTrainer(("lfd",), ("cloning",), acts=False),
    "bco": OwnTrainer(("lfo",), ("cloning",)),
    "iq-learn": OwnTrainer(("lfd", "lfo"), ("sac", "iq"), sac_preset="iq-learn"),
}

#: Every name ``--method`` accepts.
ALL_METHODS: tuple[str, ...] = (*METHODS, *OWN_TRAINER_METHODS)
