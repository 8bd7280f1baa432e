"""``TrainConfig``: every setting of a ``rankgame train`` run, as nested typed configs, one per piece.

The method's pieces each own their settings (:class:`~rankgame.game.rankings.RankingsConfig`,
:class:`~rankgame.reward.player.RewardConfig`, :class:`~rankgame.game.leaders.LeaderConfig`,
:class:`~rankgame.policy.sac.SACConfig`); this module adds the non-stationary switch, the ablation
options and the run itself, and checks them together once (:meth:`TrainConfig.validate`). Field
docstrings become ``rankgame train --help``; nested configs become option groups (``--rankings.k``).
"""

from __future__ import annotations

import dataclasses
import json
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, TypeVar, Union, get_args, get_origin

from rankgame.baselines.cloning import CloningConfig
from rankgame.baselines.iq import IQConfig
from rankgame.errors import RankGameError, invalid_choices
from rankgame.game.leaders import LEADERS, Budget, BudgetRows, LeaderConfig
from rankgame.game.methods import ALL_METHODS, METHODS, OWN_TRAINER_METHODS
from rankgame.game.rankings import Mixup, RankingsConfig
from rankgame.game.recipes import setting_value
from rankgame.policy.opolo import OPOLOConfig
from rankgame.policy.ppo import PPOConfig
from rankgame.policy.sac import SAC_PRESETS, SACConfig
from rankgame.policy.td3 import TD3Config
from rankgame.reward.inputs import RewardInput
from rankgame.reward.losses import LOSSES
from rankgame.reward.player import RewardConfig


@dataclass(frozen=True)
class SwitchConfig:
    """Non-stationary imitation (Sec. 5.3): the task and/or the expert change during the run."""

    at: int | None = None
    """Environment steps after which the task switches to --switch.env and/or the expert to
    --switch.expert; default: never."""
    env: str | None = None
    """Task to train and evaluate on after --switch.at, with the same spaces as ENV (e.g.
    rankgame/HopperHeavy-v5: changed dynamics); default: ENV throughout."""
    expert: Path | None = None
    """Expert data to imitate after --switch.at (e.g. an expert of rankgame/HopperBackward-v5: changed
    intent), recorded on --switch.env if given, else on ENV; scores are then normalized by its returns.
    Default: the shipped data of --switch.env if there is any, else the same expert throughout. The pref
    methods take neither (their offline rankings lie below the first expert)."""


@dataclass(frozen=True)
class AblationConfig:
    """Options outside the paper's method, for its ablations (App. D; benchmarks/ablations.py)."""

    budget: Literal["leader", "holdout", "passes"] = "leader"
    """How long the reward trains each iteration: the leader's own budget, or the other one (holdout:
    until the holdout loss stops improving; passes: n_rew = ral_passes |D| / batch_size steps)."""
    budget_rows: BudgetRows = "real"
    """Which agent rows size the budgets: real states only, or all rows with the absorbing padding of
    early-terminated episodes, as the authors' code does."""
    spectral_norm: bool = False
    """Divide every reward layer by its spectral norm (a 1-Lipschitz reward; a regularizer the paper
    compares the auto rankings with)."""
    mixup: Mixup = "trajectory"
    """How the auto rankings pair agent and expert states: trajectory (time-aligned, the paper's) or
    state (an expert state from a random time step)."""

    @property
    def leader_budget(self) -> Budget | None:
        """The budget that replaces the leader's own, or None."""
        return None if self.budget == "leader" else self.budget


@dataclass(frozen=True)
class TrainConfig:
    """Options of ``rankgame train``."""

    env: str = "Hopper-v5"
    """Gymnasium id of the task."""
    method: Literal[
        "rank-pal-auto",
        "rank-ral-auto",
        "rank-pal-vanilla",
        "rank-ral-vanilla",
        "rank-pal-pref",
        "rank-ral-pref",
        "imit-pal",
        "imit-ral",
        "gail",
        "gaifo",
        "dac",
        "dacfo",
        "trex",
        "f-irl",
        "opolo",
        "bc",
        "bco",
        "iq-learn",
    ] = "rank-pal-auto"
    """Rankings x loss x leader x policy player (see rankgame.game.methods and docs/methods.md)."""
    steps: int = 300_000
    """Environment steps of training (for bc, which never acts: gradient steps)."""
    seed: int = 0
    """Seed of everything random in the run."""
    out: Path = Path("runs/train")
    """Output folder: metrics.csv, tb/, checkpoint.npz, policy.msgpack (the actor of the last evaluation)."""
    expert: Path | None = None
    """Expert trajectory file, or minari:DATASET_ID (default: the shipped data for ENV)."""
    expert_trajectories: int = 1
    """How many expert trajectories to imitate (the first ones of the file)."""
    preferences: Path | None = None
    """Offline trajectories ranked below the expert, for the pref methods (default: the shipped data
    for ENV; make a file with `rankgame preferences`)."""
    setting: Literal["lfo", "lfd"] | None = None
    """Learn from observations only (lfo) or from observations and actions (lfd); default: lfd for
    gail, dac, bc and iq-learn, lfo for every other method."""
    reward_input: Literal["default", "s", "ss", "sa"] = "default"
    """Reward inputs: s, (s, s') or (s, a); default: sa for lfd, and for lfo (s, s') with gaifo and
    dacfo, s with the others."""
    reward_obs: str = "all"
    """Observation entries the reward reads: all, or indices and half-open ranges such as 0:27."""
    policy_updates: int | None = None
    """Environment steps (and SAC updates) per game iteration, n_pol; default: the horizon H."""
    eval_every: int = 10_000
    """Environment steps between evaluations of the deterministic policy on the true reward."""
    eval_episodes: int = 5
    """Episodes per evaluation."""
    checkpoint_every: int = 20_000
    """Environment steps between checkpoints (rounded to whole iterations); the last step always gets one."""
    resume: bool = False
    """Continue the run in OUT from its last checkpoint, with the settings saved there."""
    tensorboard: bool = True
    """Also write TensorBoard event files to OUT/tb, with the settings as hyperparameters."""
    wandb: bool = False
    """Also log to Weights & Biases (the wandb extra): the settings, every evaluation row and the final
    policy, offline under OUT/wandb unless WANDB_MODE=online (upload later with wandb sync)."""
    progress: bool = True
    """Show a progress bar."""
    rankings: RankingsConfig = field(default_factory=RankingsConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    leader: LeaderConfig = field(default_factory=LeaderConfig)
    sac: SACConfig = field(default_factory=SACConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    td3: TD3Config = field(default_factory=TD3Config)
    opolo: OPOLOConfig = field(default_factory=OPOLOConfig)
    cloning: CloningConfig = field(default_factory=CloningConfig)
    iq: IQConfig = field(default_factory=IQConfig)
    switch: SwitchConfig = field(default_factory=SwitchConfig)
    ablation: AblationConfig = field(default_factory=AblationConfig)

    @property
    def resolved_setting(self) -> Literal["lfo", "lfd"]:
        """``setting``, or the method's own when it is None."""
        if self.method in OWN_TRAINER_METHODS:
            return self.setting or OWN_TRAINER_METHODS[self.method].settings[0]
        return self.setting or METHODS[self.method].settings[0]

    @property
    def resolved_reward_input(self) -> RewardInput:
        if self.reward_input != "default":
            return self.reward_input
        if self.resolved_setting == "lfd":
            return "sa"
        return METHODS[self.method].lfo_input if self.method in METHODS else "s"

    def validate(self) -> None:
        """Raise :class:`RankGameError` with a one-line reason for settings that make no sense."""
        if self.method not in ALL_METHODS:
            raise RankGameError(f"unknown method {self.method!r}; choose from {', '.join(ALL_METHODS)}")
        if invalid := invalid_choices(self):
            raise RankGameError(f"bad setting: {invalid[0]}")
        positive = {
            "--steps": self.steps,
            "--eval-every": self.eval_every,
            "--eval-episodes": self.eval_episodes,
            "--expert-trajectories": self.expert_trajectories,
            "--checkpoint-every": self.checkpoint_every,
        }
        for name, value in positive.items():
            if value <= 0:
                raise RankGameError(f"{name} must be positive (got {value})")
        if self.seed < 0:
            raise RankGameError(f"--seed must be >= 0 (got {self.seed})")
        if self.policy_updates is not None and self.policy_updates <= 0:
            raise RankGameError("--policy-updates must be positive")
        if self.method in OWN_TRAINER_METHODS:
            self._validate_own_trainer()
        else:
            self._validate_game()

    def _validate_own_trainer(self) -> None:
        settings = OWN_TRAINER_METHODS[self.method].settings
        if self.resolved_setting not in settings:
            raise RankGameError(f"{self.method} learns only {_LEARNS[settings[0]]}, not with --setting {self.setting}")
        if unused := unused_settings(self):
            raise RankGameError(f"{unused[0]} is not used by {self.method}")
        try:
            self.cloning.validate()
            self.iq.validate()
            self.sac.validate()
        except ValueError as exc:
            raise RankGameError(f"bad setting: {exc}") from None

    def _validate_game(self) -> None:
        method = METHODS[self.method]
        if self.ablation.mixup != "trajectory" and method.rankings != "auto":
            raise RankGameError(f"--ablation.mixup is used only by the auto methods, not {self.method}")
        if self.preferences is not None and not method.uses_preferences:
            raise RankGameError(f"--preferences is used only by the pref methods and trex, not {self.method}")
        if self.rankings.pref_noise > 0.0 and not method.uses_preferences:
            raise RankGameError(f"--rankings.pref-noise is used only by the pref methods and trex, not {self.method}")
        switch = self.switch
        if (switch.at is not None) != (switch.env is not None or switch.expert is not None):
            raise RankGameError("--switch.at needs --switch.env or --switch.expert, and they need --switch.at")
        if switch.at is not None and not 0 < switch.at < self.steps:
            raise RankGameError(f"--switch.at must lie between 0 and --steps {self.steps} (got {switch.at})")
        if switch.expert is not None and method.uses_preferences:
            raise RankGameError("--switch.expert cannot be combined with the pref methods' offline rankings")
        if switch.expert is not None and method.policy == "opolo":
            raise RankGameError(
                "--switch.expert cannot be combined with opolo, whose policy regularizer reads the first expert"
            )
        if switch.expert is None and switch.env is not None and method.uses_preferences:
            from rankgame.data.experts import shipped_envs

            if switch.env in shipped_envs():  # plan_switch would imitate its shipped expert after the switch
                raise RankGameError(
                    f"--switch.env {switch.env} brings its shipped expert, which the pref methods' offline rankings "
                    "(below the first expert) cannot follow: use a --switch.env without shipped expert data "
                    f"(changed dynamics, e.g. rankgame/HopperHeavy-v5) or a --method other than {self.method}"
                )
        if self.resolved_setting not in method.settings:
            raise RankGameError(
                f"{self.method} learns only {_LEARNS[method.settings[0]]}, not with --setting {self.setting}"
            )
        if self.resolved_setting == "lfo" and self.resolved_reward_input == "sa":
            raise RankGameError("--reward-input sa needs expert actions: use --setting lfd")
        if self.rankings.still_poses == "expert" and self.resolved_reward_input != "ss":
            raise RankGameError("--rankings.still-poses expert ranks self-transitions (s, s): use --reward-input ss")
        try:
            self.rankings.validate(method.rankings)
            self.reward.validate()
            self.leader.validate()
            self.sac.validate()
            self.ppo.validate()
            self.td3.validate()
            self.opolo.validate()
        except ValueError as exc:
            raise RankGameError(f"bad setting: {exc}") from None
        if unused := unused_settings(self):
            raise RankGameError(f"{unused[0]} is not used by {self.method}")
        if LOSSES[method.loss].regresses_targets and self.rankings.k > self.reward.r_max:
            raise RankGameError(
                f"targets [0, {self.rankings.k}] exceed the reward bound [-{self.reward.r_max}, {self.reward.r_max}] "
                "(--reward.r-max)"
            )


_LEARNS = {"lfd": "from demonstrations (lfd)", "lfo": "from observations (lfo)"}

#: The options of standing still ranked below the expert (regression sources and losses only).
_STILL_OPTIONS = ("rankings.still_weight", "rankings.still_poses")
#: The options each piece reads, by dotted name; an option that no piece of a method reads must keep its
#: default for that method (``unused_settings``).
_RANKINGS_OPTIONS: dict[str, tuple[str, ...]] = {
    "vanilla": ("rankings.k", *_STILL_OPTIONS),
    "auto": ("rankings.k", "rankings.schedule", "rankings.beta", "rankings.interpolations", *_STILL_OPTIONS),
    "pref": (
        "rankings.k",
        *_STILL_OPTIONS,
        "rankings.schedule",
        "rankings.beta",
        "rankings.pref_weight",
        "rankings.pref_noise",
        "rankings.snippet_length",
    ),
    "offline": ("rankings.pref_noise", "rankings.snippet_length"),
    "marginal": ("rankings.divergence", "rankings.ratio_steps"),
}
_BUDGET_OPTIONS: dict[str, tuple[str, ...]] = {
    "holdout": ("leader.holdout_fraction", "leader.patience", "leader.max_epochs"),
    "passes": ("leader.holdout_fraction", "leader.ral_passes"),
    "fixed": ("leader.holdout_fraction", "leader.gda_steps"),
    "opening": ("leader.opening_steps",),
}


#: The run's own options, which every method reads.
_RUN_OPTIONS = (
    "env",
    "method",
    "steps",
    "seed",
    "out",
    "expert",
    "expert_trajectories",
    "setting",
    "eval_every",
    "eval_episodes",
    "checkpoint_every",
    "resume",
    "tensorboard",
    "wandb",
    "progress",
)


def unused_settings(config: TrainConfig) -> list[str]:
    """The ``--`` names of options set away from their defaults that no piece of ``config.method`` reads."""
    defaults = TrainConfig()
    if config.method in OWN_TRAINER_METHODS:
        reads = (*_RUN_OPTIONS, *OWN_TRAINER_METHODS[config.method].groups)
        names = [
            f.name
            for f in dataclasses.fields(TrainConfig)
            if f.name not in reads and getattr(config, f.name) != getattr(defaults, f.name)
        ]
        if "sac" in names and config.sac in SAC_PRESETS.values():
            names.remove("sac")
        return [
            "--" + name.replace("_", "-") + (".*" if dataclasses.is_dataclass(getattr(config, name)) else "")
            for name in names
        ]
    method = METHODS[config.method]
    unused = [
        *(f"rankings.{f.name}" for f in dataclasses.fields(RankingsConfig)),
        *(f"leader.{f.name}" for f in dataclasses.fields(LeaderConfig)),
    ]
    budget = config.ablation.leader_budget or LEADERS[method.leader][1]
    used = set(_RANKINGS_OPTIONS[method.rankings]) | set(_BUDGET_OPTIONS[budget])
    if not LOSSES[method.loss].regresses_targets:  # standing still is ranked by regressing targets
        used.difference_update(_STILL_OPTIONS)
    if LOSSES[method.loss].gradient_penalty or method.rankings in ("offline", "marginal"):
        unused.append("reward.ranking_gradient_penalty")
    if not LOSSES[method.loss].gradient_penalty:
        unused.append("reward.gradient_penalty")
    if budget == "opening":  # one fixed reward: nothing to average
        unused.append("reward.policy_window")
    names = [
        name for name in unused if name not in used and setting_value(config, name) != setting_value(defaults, name)
    ]
    if method.policy != "sac" and config.sac not in SAC_PRESETS.values():
        names.append("sac.*")
    if method.policy != "ppo" and config.ppo != PPOConfig():
        names.append("ppo.*")
    if method.policy != "opolo" and config.td3 != TD3Config():
        names.append("td3.*")
    if method.policy != "opolo" and config.opolo != OPOLOConfig():
        names.append("opolo.*")
    if config.cloning != CloningConfig():
        names.append("cloning.*")
    if config.iq != IQConfig():
        names.append("iq.*")
    return ["--" + name.replace("_", "-") for name in names]


def config_to_json(config: Any) -> dict[str, Any]:
    """A config dataclass as plain JSON data (paths as strings, tuples as lists)."""
    return json.loads(json.dumps(dataclasses.asdict(config), default=str))


Config = TypeVar("Config")


def config_from_json(cls: type[Config], data: dict[str, Any]) -> Config:
    """Inverse of :func:`config_to_json` for the dataclass ``cls``; a one-line :class:`RankGameError` for
    an unknown option or a value of the wrong type."""
    hints = typing.get_type_hints(cls)
    values: dict[str, Any] = {}
    for name, value in data.items():
        if name not in hints:
            raise RankGameError(f"unknown option {name!r} in a saved {cls.__name__}")
        values[name] = _from_json(hints[name], value, name)
    return cls(**values)


def _from_json(annotation: Any, value: Any, name: str) -> Any:
    origin, args = get_origin(annotation), get_args(annotation)
    if dataclasses.is_dataclass(annotation) and isinstance(value, dict):
        return config_from_json(annotation, value)  # type: ignore[arg-type]
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _from_json(inner[0], value, name)
    if origin is tuple and isinstance(value, list):
        return tuple(_from_json(args[0], v, name) for v in value)
    if origin is Literal and value in args:
        return value
    if annotation is Path and isinstance(value, str):
        return Path(value)
    if annotation is float and isinstance(value, int | float) and not isinstance(value, bool):
        return float(value)
    if annotation in (int, str, bool) and type(value) is annotation:
        return value
    raise RankGameError(f"saved option {name!r} has a value of the wrong type: {value!r}")
