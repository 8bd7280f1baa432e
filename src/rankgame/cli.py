"""The ``rankgame`` command line: ``train``, ``evaluate``, ``expert``, ``record``, ``preferences``, ``experts``,
``plot``, ``export-reward`` and ``data``.

Options are generated from the config dataclasses (see :mod:`rankgame.cli_args`). A ``--preset``
picks the defaults the other options start from, and ``--help`` shows that preset's values. With
``--resume`` a run takes its settings from its folder; options given explicitly must agree with them.
Every user error ends in one line on stderr and a non-zero exit status (1; 2 for a command line that is
itself wrong; 130 or 143 for a run stopped by SIGINT or SIGTERM after its checkpoint).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TypeVar

from rankgame.cli_args import add_dataclass_options, dataclass_from_args, explicit_dests
from rankgame.errors import RankGameError, RunInterrupted, UsageError

if TYPE_CHECKING:
    from rankgame.config import TrainConfig

PROG = "rankgame"

#: Spellings of ``rankgame train`` options before they moved into their piece's group; still accepted.
LEGACY_SPELLINGS = {
    "--k": "--rankings.k",
    "--schedule": "--rankings.schedule",
    "--beta": "--rankings.beta",
    "--interpolations": "--rankings.interpolations",
    "--pref-noise": "--rankings.pref-noise",
    "--reward.pref-weight": "--rankings.pref-weight",
    "--reward.snippet-length": "--rankings.snippet-length",
    "--reward.holdout-fraction": "--leader.holdout-fraction",
    "--reward.patience": "--leader.patience",
    "--reward.max-epochs": "--leader.max-epochs",
    "--reward.ral-passes": "--leader.ral-passes",
    "--switch-at": "--switch.at",
    "--switch-env": "--switch.env",
    "--switch-expert": "--switch.expert",
    "--reward.budget": "--ablation.budget",
    "--reward.budget-rows": "--ablation.budget-rows",
    "--reward.spectral-norm": "--ablation.spectral-norm",
    "--no-reward.spectral-norm": "--no-ablation.spectral-norm",
    "--mixup": "--ablation.mixup",
}


def _modern_spelling(argv: Sequence[str]) -> list[str]:
    """``argv`` with the options of :data:`LEGACY_SPELLINGS` renamed (``--k 1`` and ``--k=1`` alike)."""
    renamed = []
    for arg in argv:
        name, eq, value = arg.partition("=")
        renamed.append(LEGACY_SPELLINGS.get(name, name) + eq + value if name.startswith("--") else arg)
    return renamed


#: A command's config dataclass (``TrainConfig``, ``ExpertConfig``).
Config = TypeVar("Config")


class _Parser(argparse.ArgumentParser):
    """ArgumentParser whose errors are one line: ``rankgame: error: ...``."""

    def __init__(self, **kwargs: Any) -> None:
        # Options read ahead of parsing (--preset, --recipe, --env, --method) must be spelled in full.
        super().__init__(allow_abbrev=False, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def _value_from_argv(argv: Sequence[str], option: str, default: str) -> str:
    """Read ``OPTION VALUE`` ahead of full parsing, so that it can set the defaults of other options.

    A missing value gives ``default`` here; the full parse then reports it.
    """
    for i, arg in enumerate(argv):
        if arg == option and i + 1 < len(argv) and not argv[i + 1].startswith("--"):
            return argv[i + 1]
        if arg.startswith(option + "="):
            return arg.split("=", 1)[1]
    return default


def _config_with_sac_preset(
    argv: Sequence[str],
    command: str,
    description: str,
    make_config: Callable[..., Config],
    default_preset: str,
    add_options: Callable[[argparse.ArgumentParser], None] | None = None,
) -> tuple[Config, set[str]]:
    """Parse ``argv`` into the config made by ``make_config(sac=preset)``; ``--preset`` sets the SAC defaults.

    ``add_options`` adds options that are not fields of the config (read ahead by ``make_config``).
    Returns the config and the dotted names of the options given explicitly (an explicit ``--preset``
    counts as every ``sac.*`` option).
    """
    from rankgame.policy.sac import SAC_PRESETS

    preset = _value_from_argv(argv, "--preset", default_preset)
    if preset not in SAC_PRESETS:
        raise UsageError(f"unknown preset {preset!r}; choose from {', '.join(SAC_PRESETS)}")
    default = make_config(sac=SAC_PRESETS[preset])
    parser = _Parser(prog=f"{PROG} {command}", usage=f"{PROG} {command} [options]", description=description)
    parser.add_argument(
        "--preset", choices=list(SAC_PRESETS), default=preset, help=f"SAC preset (default: {default_preset})"
    )
    if add_options is not None:
        add_options(parser)
    add_dataclass_options(parser, default)
    config = dataclass_from_args(parser.parse_args(argv), default)
    explicit = explicit_dests(parser, argv)
    if "preset" in explicit:
        explicit |= {f"sac.{f.name}" for f in dataclasses.fields(default.sac)}  # type: ignore[attr-defined]
    return config, explicit


def _saved_settings(out: Path) -> dict[str, Any] | None:
    """The settings of the run in ``out`` (its checkpoint's, else its ``config.json``); None if it has none."""
    from rankgame.checkpoint import CHECKPOINT_NAME, load_checkpoint

    if (out / CHECKPOINT_NAME).is_file():
        return load_checkpoint(out / CHECKPOINT_NAME)[0]["config"]
    if not (out / "config.json").is_file():
        return None
    try:
        saved = json.loads((out / "config.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise RankGameError(f"{out / 'config.json'}: unreadable run settings ({exc})") from None
    if not isinstance(saved, dict):
        raise RankGameError(f"{out / 'config.json'}: unreadable run settings (not a JSON object)")
    saved.pop("command", None)
    saved.pop("resumed_with", None)
    return saved


def _resumed_config(config: Config, explicit: set[str]) -> Config:
    """With ``--resume``, the run's own settings from its folder, run-control options given explicitly
    applied; an explicit option that differs from the run's is refused by name. Without ``--resume``, or
    for a folder with no saved settings (the harness then says why it cannot resume), ``config``."""
    from rankgame.checkpoint import RUN_CONTROL_OPTIONS, flatten_options, option_name
    from rankgame.config import config_from_json, config_to_json

    out = Path(config.out)  # type: ignore[attr-defined]
    if not config.resume:  # type: ignore[attr-defined]
        return config
    saved = _saved_settings(out)
    if saved is None:
        return config
    given, was = flatten_options(config_to_json(config)), flatten_options(saved)
    for name in sorted(explicit):
        if name.split(".")[0] not in RUN_CONTROL_OPTIONS and name in given and given[name] != was.get(name):
            raise RankGameError(
                f"{option_name(name)} {given[name]} differs from the run's {was.get(name)} in {out}; a resumed run "
                "keeps its settings"
            )
    run_control = {
        name: getattr(config, name) for name in RUN_CONTROL_OPTIONS - {"resume"} if name in explicit or name == "out"
    }
    return dataclasses.replace(config_from_json(type(config), saved), **run_control, resume=True)


def _cmd_expert(argv: Sequence[str]) -> int:
    from rankgame.expert import ExpertConfig, train_expert

    description = "Train a SAC expert on the true reward, then record trajectories of its best policy."
    cfg, explicit = _config_with_sac_preset(argv, "expert", description, ExpertConfig, "modern")
    cfg = _resumed_config(cfg, explicit)
    _print_json(train_expert(cfg, command=shlex.join([PROG, "expert", *argv])))
    return 0


def _print_json(summary: dict[str, Any]) -> None:
    """A command's summary as valid JSON: NaN and infinite numbers become null."""
    from rankgame.run import finite_or_none

    print(json.dumps(finite_or_none(summary), indent=2, allow_nan=False))


def _resume_in_argv(argv: Sequence[str]) -> bool:
    """Whether ``argv`` asks to resume (the last of ``--resume`` and ``--no-resume`` decides)."""
    flags = [arg for arg in argv if arg in ("--resume", "--no-resume")]
    return bool(flags) and flags[-1] == "--resume"


def _saved_str(saved: dict[str, Any], name: str, default: str) -> str:
    value = saved.get(name)
    return value if isinstance(value, str) else default


def train_config_from_argv(argv: Sequence[str]) -> tuple[TrainConfig, str | None]:
    """Parse ``rankgame train`` options: the config, and a note on what ``--recipe`` changed (None for paper).

    The SAC preset and the recipe of ``--env`` and ``--method`` set the defaults; options given
    explicitly override them. With ``--resume`` the run's saved settings are the config, and the recipe
    is that of the run's task and method unless ``--env`` or ``--method`` is given.
    """
    from rankgame.config import TrainConfig
    from rankgame.game.methods import OWN_TRAINER_METHODS
    from rankgame.game.recipes import RECIPES, recipe_settings, setting_value, with_settings
    from rankgame.policy.sac import SACConfig

    argv = _modern_spelling(argv)

    recipe = _value_from_argv(argv, "--recipe", "paper")
    if recipe not in RECIPES:
        raise UsageError(f"unknown recipe {recipe!r}; choose from {', '.join(RECIPES)}")
    # A resumed run's recipe is that of its own task and method, unless they are given.
    saved: dict[str, Any] = {}
    if _resume_in_argv(argv):
        saved = _saved_settings(Path(_value_from_argv(argv, "--out", str(TrainConfig.out)))) or {}
    env = _value_from_argv(argv, "--env", _saved_str(saved, "env", TrainConfig.env))
    method = _value_from_argv(argv, "--method", _saved_str(saved, "method", TrainConfig.method))
    settings = recipe_settings(recipe, env, method)

    def make_config(sac: SACConfig) -> TrainConfig:
        return with_settings(TrainConfig(sac=sac), settings)

    def add_recipe(parser: argparse.ArgumentParser) -> None:
        parser.add_argument(
            "--recipe",
            choices=list(RECIPES),
            default=recipe,
            help="Per-task settings: paper (Table 4 everywhere) or tuned (docs/recipes.md); the defaults "
            "below include it, explicit options override it (default: paper)",
        )

    description = (
        "Imitate an expert by playing the ranking game (RANK-PAL / RANK-RAL / IMIT), or with a baseline in the "
        "same harness (GAIL, GAIfO, DAC, DACfO, T-REX, BC, BCO, IQ-Learn; see docs/methods.md)."
    )
    own = OWN_TRAINER_METHODS.get(method)
    default_preset = own.sac_preset if own is not None and own.sac_preset is not None else "paper"
    cfg, explicit = _config_with_sac_preset(argv, "train", description, make_config, default_preset, add_recipe)
    if "recipe" in explicit:
        explicit |= set(settings)
    if cfg.resume:
        return _resumed_config(cfg, explicit), None
    if recipe == "paper":
        return cfg, None
    changes = [
        f"--{name.replace('_', '-')} {value}" + ("" if setting_value(cfg, name) == value else " (overridden)")
        for name, value in settings.items()
    ]
    summary = ", ".join(changes) or "no tuned settings for this pair, the paper's apply"
    return cfg, f"--recipe {recipe} for {cfg.method} on {cfg.env}: {summary}"


def _cmd_train(argv: Sequence[str]) -> int:
    from rankgame.training import train

    cfg, recipe_note = train_config_from_argv(argv)
    if recipe_note is not None:
        print(recipe_note, file=sys.stderr)
    _print_json(train(cfg, command=shlex.join([PROG, "train", *argv])))
    return 0


@dataclasses.dataclass(frozen=True)
class RecordConfig:
    """Options of ``rankgame record``."""

    policy: Path = Path("runs/expert/best_policy.msgpack")
    """Saved policy to roll out (deterministically)."""
    out: Path = Path("runs/expert/trajectories.npz")
    """Trajectory file to write."""
    episodes: int = 10
    """Episodes to record."""
    seed: int = 0
    """Seed of the first episode's reset (episode i uses seed + i)."""
    random_episodes: int = 100
    """Episodes of a uniformly random policy, for the random return in the metadata."""
    successful_only: bool = False
    """Keep only episodes that succeed (tasks that report success, such as rankgame/Pen-v0): episodes
    seed, seed + 1, ... are rolled out until --episodes of them succeed."""


def _cmd_record(argv: Sequence[str]) -> int:
    from rankgame.expert import record_expert

    parser = _Parser(prog=f"{PROG} record", description="Record trajectories of a saved policy.")
    add_dataclass_options(parser, RecordConfig())
    cfg = dataclass_from_args(parser.parse_args(argv), RecordConfig())
    if cfg.episodes <= 0 or cfg.random_episodes <= 0:
        raise RankGameError("--episodes and --random-episodes must be positive")
    if cfg.seed < 0:
        raise RankGameError(f"--seed must be >= 0 (got {cfg.seed})")
    summary = record_expert(
        cfg.policy,
        cfg.out,
        cfg.episodes,
        cfg.seed,
        cfg.random_episodes,
        successful_only=cfg.successful_only,
        command=shlex.join([PROG, "record", *argv]),
    )
    print(json.dumps(summary, indent=2))
    return 0


@dataclasses.dataclass(frozen=True)
class PreferencesConfig:
    """Options of ``rankgame preferences``."""

    run: Path = Path("runs/expert")
    """Folder of a `rankgame expert` run; its checkpoint.npz holds the replay buffer to draw from."""
    out: Path = Path("runs/preferences.npz")
    """Trajectory file to write (pass it to `rankgame train --preferences`)."""
    count: int = 10
    """Complete episodes to draw uniformly, without replacement (the paper uses 10)."""
    seed: int = 0
    """Seed of the draw."""


def _cmd_preferences(argv: Sequence[str]) -> int:
    from rankgame.data.preferences import sample_preferences

    description = (
        "Draw episodes uniformly from the replay buffer of a SAC run on the true reward, as offline rankings "
        "(ranked by true return) for the pref methods."
    )
    parser = _Parser(prog=f"{PROG} preferences", description=description)
    add_dataclass_options(parser, PreferencesConfig())
    cfg = dataclass_from_args(parser.parse_args(argv), PreferencesConfig())
    command = shlex.join([PROG, "preferences", *argv])
    print(json.dumps(sample_preferences(cfg.run, cfg.out, cfg.count, cfg.seed, command=command), indent=2))
    return 0


def _cmd_evaluate(argv: Sequence[str]) -> int:
    from rankgame.evaluate import EvaluateConfig, evaluate_policy

    parser = _Parser(prog=f"{PROG} evaluate", description="Return and normalized score of a saved policy.")
    add_dataclass_options(parser, EvaluateConfig())
    _print_json(evaluate_policy(dataclass_from_args(parser.parse_args(argv), EvaluateConfig())))
    return 0


def _cmd_experts(argv: Sequence[str]) -> int:
    from rankgame.data.experts import expert_table

    parser = _Parser(prog=f"{PROG} experts", description="List the expert data shipped with rankgame.")
    parser.add_argument("--json", action="store_true", help="print JSON instead of a table")
    args = parser.parse_args(argv)
    rows = expert_table()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    width = max([16, *(len(row["env"]) + 2 for row in rows)])
    header = f"{'env':<{width}}{'trajs':>6}{'length':>8}{'return':>12}{'std':>9}{'random':>10}"
    print(header)
    for row in rows:
        print(
            f"{row['env']:<{width}}{row['trajectories']:>6}{row['mean_length']:>8.0f}"
            f"{row['return_mean']:>12.1f}{row['return_std']:>9.1f}{row['random_return']:>10.1f}"
        )
    return 0


def _cmd_plot(argv: Sequence[str]) -> int:
    from rankgame.plot import plot_runs

    parser = _Parser(prog=f"{PROG} plot", description="Plot learning curves of run folders (metrics.csv).")
    parser.add_argument("runs", nargs="+", type=Path, help="run folders written by rankgame train or expert")
    parser.add_argument("--column", default="normalized_score", help="metrics.csv column (default: normalized_score)")
    parser.add_argument("--out", type=Path, default=Path("curves.png"), help="image to write (default: curves.png)")
    parser.add_argument(
        "--seeds",
        action="store_true",
        help="one curve per group of runs whose names differ only in a seed suffix (_s0, -seed1): "
        "the mean over seeds with a one-standard-deviation band",
    )
    parser.add_argument(
        "--labels", nargs="+", help="legend names, one per curve in order (default: the run or group folder names)"
    )
    parser.add_argument("--title", help="title above the plot")
    parser.add_argument(
        "--max-steps", type=int, help="end every curve at this many environment steps (default: where each run ends)"
    )
    args = parser.parse_args(argv)
    out = plot_runs(
        args.runs,
        args.out,
        args.column,
        seeds=args.seeds,
        labels=args.labels,
        title=args.title,
        max_steps=args.max_steps,
    )
    print(out)
    return 0


def _cmd_sweep(argv: Sequence[str]) -> int:
    from rankgame.sweep import SweepSpec, load_spec, parse_variant, run_sweep

    parser = _Parser(
        prog=f"{PROG} sweep",
        description="Run a grid of rankgame train runs (envs x methods x seeds x variants) on Ray Tune: one "
        "run folder per trial in --out, ENV__METHOD__sSEED[__VARIANT]. Needs the sweep extra (Ray).",
    )
    parser.add_argument("--spec", type=Path, help="a TOML file with envs, methods, seeds, steps, variants, options")
    parser.add_argument("--envs", nargs="+", help="tasks (Gymnasium ids)")
    parser.add_argument("--methods", nargs="+", help="methods of rankgame train --method")
    parser.add_argument("--seeds", nargs="+", type=int, help="seeds")
    parser.add_argument("--steps", type=int, help="environment steps of every trial")
    parser.add_argument(
        "--variant",
        action="append",
        default=[],
        metavar="NAME=VALUE[,NAME=VALUE...]",
        help="a set of rankgame train options, one trial per cell for each --variant (repeat it); e.g. "
        "--variant reward.lr=1e-4 --variant reward.lr=3e-4",
    )
    parser.add_argument(
        "--option",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a rankgame train option of every trial, e.g. --option eval-episodes=10 (repeat it)",
    )
    parser.add_argument("--out", type=Path, required=True, help="the sweep folder")
    parser.add_argument("--resume", action="store_true", help="continue the sweep in --out (same grid)")
    parser.add_argument("--cores", type=int, help="trials at once on this machine (default: its cores)")
    parser.add_argument("--address", help="join a running Ray cluster (HOST:6379, or auto)")
    parser.add_argument("--storage", help="where Ray keeps its experiment state (default: OUT/.ray)")
    parser.add_argument("--max-failures", type=int, default=3, help="restarts of a trial whose worker died")
    args = parser.parse_args(argv)
    grid_args = {"envs": args.envs, "methods": args.methods, "seeds": args.seeds, "steps": args.steps}
    if args.spec is not None:
        spec = load_spec(args.spec)
        given = [f"--{name}" for name, value in grid_args.items() if value is not None]
        if given or args.variant or args.option:
            raise UsageError(f"--spec holds the grid: drop {', '.join(given) or '--variant/--option'}")
    else:
        if missing := [f"--{name}" for name, value in grid_args.items() if value is None]:
            raise UsageError(f"the grid needs {', '.join(missing)} (or --spec FILE)")
        variants = dict(parse_variant(text) for text in args.variant)
        options = {k: v for text in args.option for k, v in parse_variant(text)[1].items()}
        spec = SweepSpec(tuple(args.envs), tuple(args.methods), tuple(args.seeds), args.steps, variants, options)
    summary = run_sweep(
        spec,
        args.out,
        resume=args.resume,
        cores=args.cores,
        address=args.address,
        storage=args.storage,
        max_failures=args.max_failures,
    )
    _print_json(summary)
    return 1 if summary["failed"] else 0


def _cmd_report(argv: Sequence[str]) -> int:
    from rankgame.report import write_report

    parser = _Parser(
        prog=f"{PROG} report",
        description="Write a results page (OUT/results.md, figures in OUT/img/) from run folders: tables at fixed "
        "steps beside the published figures, IQM and probability of improvement with bootstrap intervals, "
        "learning curves, stability and the runs used.",
    )
    parser.add_argument(
        "runs", nargs="+", type=Path, help="run folders (config.json and metrics.csv), or folders that hold them"
    )
    parser.add_argument("--out", type=Path, required=True, help="folder to write results.md and img/ into")
    parser.add_argument(
        "--at", nargs="+", type=int, default=[100_000, 300_000], help="steps of the tables (default: 100000 300000)"
    )
    parser.add_argument("--boot", type=int, default=2000, help="bootstrap samples of the intervals (default: 2000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default: 0)")
    args = parser.parse_args(argv)
    print(write_report(args.runs, args.out, at=args.at, n_boot=args.boot, seed=args.seed))
    return 0


def _cmd_export_reward(argv: Sequence[str]) -> int:
    from rankgame.reward.export import export_reward

    parser = _Parser(
        prog=f"{PROG} export-reward",
        description="Write the learned reward of a rankgame train run as a file that load_reward() reads.",
    )
    parser.add_argument("run", type=Path, help="folder of a rankgame train run (its checkpoint.npz)")
    parser.add_argument("--out", type=Path, required=True, help="reward file to write (e.g. reward.msgpack)")
    args = parser.parse_args(argv)
    print(export_reward(args.run, args.out))
    return 0


def _cmd_data(argv: Sequence[str]) -> int:
    parser = _Parser(prog=f"{PROG} data", description="Convert trajectory data between formats.")
    commands = parser.add_subparsers(dest="action", required=True, parser_class=_Parser)
    to_minari = commands.add_parser(
        "to-minari", help="write a rankgame trajectory file as a local Minari dataset (the minari extra)"
    )
    to_minari.add_argument("file", type=Path, help="rankgame trajectory file (.npz)")
    to_minari.add_argument("dataset_id", help="Minari dataset id, such as hopper/expert-v0")
    to_minari.add_argument("--overwrite", action="store_true", help="replace a local dataset of that id")
    args = parser.parse_args(argv)
    from rankgame.data.minari import to_minari as write

    _print_json(write(args.file, args.dataset_id, overwrite=args.overwrite))
    return 0


COMMANDS = {
    "train": (_cmd_train, "imitate an expert: the ranking game (rank-pal-auto, ...) or a baseline (dacfo, bc, ...)"),
    "evaluate": (_cmd_evaluate, "roll out a saved policy: return and normalized score"),
    "expert": (_cmd_expert, "train a SAC expert on the true reward and record its trajectories"),
    "record": (_cmd_record, "record trajectories of a saved policy"),
    "preferences": (_cmd_preferences, "draw ranked trajectories from a SAC run's replay buffer (pref methods)"),
    "experts": (_cmd_experts, "list the shipped expert data"),
    "plot": (_cmd_plot, "plot learning curves of run folders"),
    "report": (_cmd_report, "write results pages (Markdown and figures) from run folders"),
    "sweep": (_cmd_sweep, "run a grid of train runs on Ray Tune, locally or on a cluster"),
    "export-reward": (_cmd_export_reward, "write the learned reward of a run for use outside rankgame"),
    "data": (_cmd_data, "convert trajectory data (to-minari: a local Minari dataset)"),
}


def _stop_on_sigterm(signum: int, _frame: Any) -> None:
    raise RunInterrupted("stopped by SIGTERM", signum)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rankgame`` command."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        lines = [f"usage: {PROG} COMMAND [options]   ({PROG} COMMAND --help for its options)", "", "commands:"]
        lines += [f"  {name:<12} {text}" for name, (_, text) in COMMANDS.items()]
        print("\n".join(lines))
        return 0 if argv else 2
    if argv[0] in ("-V", "--version"):
        from rankgame import __version__

        print(f"{PROG} {__version__}")
        return 0
    name, rest = argv[0], argv[1:]
    if name not in COMMANDS:
        print(f"{PROG}: error: unknown command {name!r}; choose from {', '.join(COMMANDS)}", file=sys.stderr)
        return 2
    # SIGTERM stops a command as SIGINT does (a run installs its own handlers while it trains).
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous_sigterm = signal.signal(signal.SIGTERM, _stop_on_sigterm) if in_main_thread else None
    try:
        return COMMANDS[name][0](rest)
    except RunInterrupted as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 128 + exc.signal_number
    except UsageError as exc:
        print(f"{PROG} {name}: error: {exc} (see --help)", file=sys.stderr)
        return 2
    except RankGameError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:  # a file or folder that cannot be read or written (permissions, full disk, ...)
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous_sigterm)


if __name__ == "__main__":
    raise SystemExit(main())
