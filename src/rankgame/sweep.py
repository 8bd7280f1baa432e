"""``rankgame sweep``: a grid of ``rankgame train`` runs on Ray Tune, locally or on a cluster (``sweep`` extra).

A sweep is envs x methods x seeds x variants, every trial one ordinary run folder inside the sweep
folder, named ``ENV__METHOD__sSEED`` (``/`` in an env id written ``__``) with ``__VARIANT`` appended for
a variant: the layout ``rankgame report`` reads. A variant is a set of ``rankgame train`` options, given
as ``name=value`` pairs (``reward.lr=1e-4,leader.patience=1``); ``options`` apply to every trial.

* **Local by default**: a Ray instance on this machine with one trial per core (``cores``), each trial a
  single-threaded process (XLA's thread pools off), the setup measured fastest on a 2-core machine.
* **A cluster**: ``address`` joins a running Ray cluster (``ray start --head`` on one node,
  ``ray start --address HEAD:6379`` on the others). Trial folders are written with ordinary file
  writes, so the sweep folder must be a path every node sees (a shared filesystem); ``storage`` is
  where Ray keeps its own experiment state (a path or any URI Ray supports; default: inside the sweep
  folder).
* **Reporting**: every evaluation of a trial goes to Ray (``tune.report``) through the training
  callback, with ``env_steps``, ``normalized_score`` and ``eval_return``, so Ray's progress table,
  schedulers and searchers see them; :func:`tune_trainable` gives the trial function for a Tuner of
  your own (ASHA, Optuna: see docs/sweeps.md).
* **Fault tolerance**: a trial whose worker dies is restarted by Ray (``max_failures``) and continues
  from its own rankgame checkpoint (``--resume``), never from step 0 and never repeating rows. A sweep
  whose driver was killed continues with ``resume=True`` (``rankgame sweep ... --resume``): the grid
  must be the one recorded in the sweep folder's ``sweep.json``, finished trials are skipped and the
  others resume from their checkpoints.

Every trial's options are parsed and checked before Ray starts, so an unknown method, env or option
stops the sweep in one line with nothing started and nothing written.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shlex
import socket
import sys
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from rankgame.atomic import atomic_write_bytes
from rankgame.errors import RankGameError

#: The sweep folder's record of its grid (and what ``--resume`` compares against).
SWEEP_FILE = "sweep.json"

#: Environment of every trial process: XLA on one thread (set before JAX is imported in the worker).
SINGLE_THREAD_ENV = {
    "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
    "OMP_NUM_THREADS": "1",
}

#: Metrics each trial reports to Ray after every evaluation.
REPORTED = ("env_steps", "normalized_score", "eval_return")


@dataclass(frozen=True)
class SweepSpec:
    """The grid of a sweep.

    Attributes:
        envs, methods, seeds: the grid's axes.
        steps: environment steps of every trial.
        variants: named option sets, ``{name: {"reward.lr": "1e-4"}}``; none means one trial per cell.
        options: ``rankgame train`` options of every trial, ``{"eval-episodes": "10"}``.
    """

    envs: tuple[str, ...]
    methods: tuple[str, ...]
    seeds: tuple[int, ...]
    steps: int
    variants: dict[str, dict[str, str]] = field(default_factory=dict)
    options: dict[str, str] = field(default_factory=dict)

    def validate(self) -> None:
        """One-line :class:`RankGameError` for an empty axis or a bad step count."""
        for name in ("envs", "methods", "seeds"):
            if not getattr(self, name):
                raise RankGameError(f"the sweep's {name} list is empty")
        if self.steps <= 0:
            raise RankGameError(f"the sweep's steps must be positive (got {self.steps})")
        if any(seed < 0 for seed in self.seeds):
            raise RankGameError("the sweep's seeds must be >= 0")
        for name in self.variants:
            if not name or "/" in name or name.startswith("."):
                raise RankGameError(f"variant name {name!r} cannot be a folder name")

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        return {**data, "envs": list(self.envs), "methods": list(self.methods), "seeds": list(self.seeds)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> SweepSpec:
        return cls(
            tuple(data["envs"]),
            tuple(data["methods"]),
            tuple(int(s) for s in data["seeds"]),
            int(data["steps"]),
            {str(k): {str(a): str(b) for a, b in v.items()} for k, v in data.get("variants", {}).items()},
            {str(k): str(v) for k, v in data.get("options", {}).items()},
        )


@dataclass(frozen=True)
class Trial:
    """One run of the grid: its folder name and its ``rankgame train`` arguments (without ``--resume``)."""

    name: str
    argv: tuple[str, ...]
    steps: int


def parse_variant(text: str) -> tuple[str, dict[str, str]]:
    """``"reward.lr=1e-4,leader.patience=1"`` -> its folder label and options; a one-line error otherwise."""
    options: dict[str, str] = {}
    for item in text.split(","):
        name, sep, value = item.strip().partition("=")
        if not sep or not name or not value:
            raise RankGameError(f"variant {text!r}: write options as name=value pairs, e.g. reward.lr=1e-4")
        options[name.removeprefix("--")] = value
    return text.replace("--", "").replace(" ", ""), options


def load_spec(path: Path) -> SweepSpec:
    """A :class:`SweepSpec` from a TOML file (see docs/sweeps.md for the layout)."""
    import tomllib

    try:
        data = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise RankGameError(f"no sweep spec at {path}") from None
    except tomllib.TOMLDecodeError as exc:
        raise RankGameError(f"{path} is not valid TOML: {exc}") from None
    known = {"envs", "methods", "seeds", "steps", "variants", "options"}
    if unknown := sorted(set(data) - known):
        raise RankGameError(f"{path}: unknown key {unknown[0]!r}; the keys are {', '.join(sorted(known))}")
    missing = [key for key in ("envs", "methods", "seeds", "steps") if key not in data]
    if missing:
        raise RankGameError(f"{path}: missing key {missing[0]!r}")
    try:
        return SweepSpec(
            tuple(str(e) for e in data["envs"]),
            tuple(str(m) for m in data["methods"]),
            tuple(int(s) for s in data["seeds"]),
            int(data["steps"]),
            {str(k): {str(a): str(b) for a, b in v.items()} for k, v in data.get("variants", {}).items()},
            {str(k): str(v) for k, v in data.get("options", {}).items()},
        )
    except (TypeError, ValueError, AttributeError) as exc:
        raise RankGameError(f"{path}: {exc}") from None


def _options_argv(options: dict[str, str]) -> list[str]:
    argv: list[str] = []
    for name, value in options.items():
        flag = "--" + name.removeprefix("--").replace("_", "-")
        if value.lower() in ("true", "false"):  # booleans are flags: --tensorboard / --no-tensorboard
            argv.append(flag if value.lower() == "true" else "--no-" + flag[2:])
        else:
            argv += [flag, *value.split()]
    return argv


def trials(spec: SweepSpec, out: Path) -> list[Trial]:
    """Every trial of ``spec`` with its run folder inside the sweep folder ``out``."""
    variants = spec.variants or {"": {}}
    result = []
    for env in spec.envs:
        for method in spec.methods:
            for seed in spec.seeds:
                for label, options in variants.items():
                    name = f"{env.replace('/', '__')}__{method}__s{seed}" + (f"__{label}" if label else "")
                    argv = ["--env", env, "--method", method, "--seed", str(seed), "--steps", str(spec.steps)]
                    argv += ["--out", str(out / name), "--no-progress", *_options_argv(spec.options)]
                    result.append(Trial(name, (*argv, *_options_argv(options)), spec.steps))
    return result


def check_trials(grid: Sequence[Trial]) -> None:
    """Parse and validate every trial's options and resolve its env and expert data, before anything runs."""
    from rankgame.cli import train_config_from_argv
    from rankgame.training import expert_data

    checked_envs: set[tuple[str, str]] = set()
    for trial in grid:
        usage = io.StringIO()
        try:
            with contextlib.redirect_stderr(usage):
                config, _ = train_config_from_argv(trial.argv)
            config.validate()
            key = (config.env, str(config.expert))
            if key not in checked_envs:
                expert_data(config, None)
                checked_envs.add(key)
        except SystemExit:  # argparse's usage error, caught above
            reason = usage.getvalue().strip().splitlines()[-1:] or ["bad options"]
            reason_text = reason[0].split(": error: ", 1)[-1].removesuffix(" (see --help)")
            raise RankGameError(f"trial {trial.name}: {reason_text}") from None
        except RankGameError as exc:
            raise RankGameError(f"trial {trial.name}: {exc}") from None


def _require_ray() -> None:
    try:
        import ray  # noqa: F401
    except ImportError:
        raise RankGameError("rankgame sweep needs Ray: pip install 'rankgame[sweep]'") from None


def launch_trials(
    todo: Sequence[Trial],
    storage: str,
    *,
    cores: int | None = None,
    address: str | None = None,
    max_failures: int = 3,
    verbose: int = 1,
) -> list[str]:
    """Run ``todo`` on Ray Tune, one single-threaded trial per CPU, each (re)starting ``rankgame train`` in
    the folder its ``--out`` names; returns the names of the trials that failed.

    Args:
        todo: the trials (their ``argv`` name an absolute ``--out``).
        storage: Ray's experiment state (a path or URI).
        cores: trials at once on this machine (default: its cores); ignored with ``address``.
        address: a running Ray cluster's address (``HOST:6379``, or ``auto``).
        max_failures: restarts of a trial whose worker died (it resumes from its own checkpoint).
        verbose: Ray's progress output (0 silent, 1 the progress table).
    Raises:
        RankGameError: Ray is missing or cannot start or be joined.
    """
    _require_ray()
    import ray
    from ray import tune

    os.environ.setdefault("RAY_AIR_NEW_OUTPUT", "0")  # the classic progress table (CLIReporter)
    # Ray runs its workers at niceness 15 by default: on a machine with other work the trials would
    # starve, and the trials are the sweep's work (a local Ray reads this when it starts).
    os.environ.setdefault("RAY_worker_niceness", "0")
    runtime_env = {"env_vars": SINGLE_THREAD_ENV}
    try:
        if address is not None:
            ray.init(address=address, runtime_env=runtime_env, log_to_driver=False)
        else:
            ray.init(
                num_cpus=cores or os.cpu_count() or 1,
                runtime_env=runtime_env,
                log_to_driver=False,
                include_dashboard=False,
            )
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise RankGameError(f"cannot start or join Ray at {address or 'this machine'}: {exc}") from None
    try:
        argv_by_name = {trial.name: list(trial.argv) for trial in todo}
        reporter = tune.CLIReporter(
            metric_columns=list(REPORTED), parameter_columns=["trial"], max_report_frequency=30, max_column_length=60
        )
        trainable = tune.with_parameters(_ray_trial, argv_by_name=argv_by_name)
        tuner = tune.Tuner(
            tune.with_resources(trainable, {"cpu": 1}),
            param_space={"trial": tune.grid_search(list(argv_by_name))},
            run_config=tune.RunConfig(
                name="rankgame-sweep",
                storage_path=storage,
                failure_config=tune.FailureConfig(max_failures=max_failures),
                progress_reporter=reporter,
                verbose=verbose,
            ),
        )
        results = tuner.fit()
        return sorted((result.config or {}).get("trial", "?") for result in results if result.error)
    finally:
        ray.shutdown()


def trial_finished(run: Path, steps: int) -> bool:
    """Whether the run folder's ``metrics.csv`` has its evaluation at ``steps`` (every run logs its last step)."""
    import csv

    path = run / "metrics.csv"
    if not path.is_file():
        return False
    with path.open(newline="") as handle:
        logged = [row.get("env_steps") or "0" for row in csv.DictReader(handle)]
    return bool(logged) and int(float(logged[-1])) >= steps


def run_trial(argv: Sequence[str], report: Callable[[dict[str, float]], None] | None = None) -> dict[str, Any]:
    """Run (or resume) one trial in this process, reporting every evaluation to ``report``.

    A folder that already holds a run (a trial restarted after its worker died) is resumed from its
    checkpoint, or from step 0 if it stopped before the first one.
    """
    from rankgame.cli import PROG, train_config_from_argv
    from rankgame.training import train

    argv = list(argv)
    out = Path(argv[argv.index("--out") + 1])
    if (out / "metrics.csv").exists() or (out / "checkpoint.npz").exists():
        argv.append("--resume")
    config, _ = train_config_from_argv(argv)

    def callback(step: int, row: dict[str, float]) -> bool:
        if report is not None:
            report({"env_steps": float(step), **{k: float(row[k]) for k in REPORTED[1:] if k in row}})
        return True

    return train(config, callback=callback, command=shlex.join([PROG, "train", *argv]))


def _ray_trial(config: dict[str, Any], argv_by_name: dict[str, list[str]]) -> None:
    """The function Ray runs for the trial ``config["trial"]`` of :func:`run_sweep`."""
    from ray import tune

    run_trial(argv_by_name[config["trial"]], tune.report)


def tune_trainable(base_argv: Sequence[str], out: str | Path) -> Callable[[dict[str, Any]], None]:
    """A Ray Tune function trainable for searches of your own: each trial runs ``rankgame train`` with
    ``base_argv`` plus the sampled options of its config (``{"reward.lr": 3e-4}``) in a folder of
    ``out`` named by those options, reporting ``env_steps``, ``normalized_score`` and ``eval_return``
    after every evaluation (use ``env_steps`` as an ASHA scheduler's ``time_attr``)."""
    base, root = tuple(base_argv), Path(out).resolve()

    def trainable(config: dict[str, Any]) -> None:
        from ray import tune

        options = {name: str(value) for name, value in sorted(config.items())}
        label = ",".join(f"{name}={value}" for name, value in options.items()) or "default"
        argv = [*base, "--out", str(root / label), "--no-progress", *_options_argv(options)]
        run_trial(argv, tune.report)

    return trainable


def check_grid(out: Path, spec: SweepSpec, resume: bool) -> None:
    """With ``resume``, check that ``out/sweep.json`` records ``spec``'s grid; without, that ``out`` holds
    no sweep yet. One-line :class:`RankGameError` otherwise; nothing is written."""
    path = out / SWEEP_FILE
    if out.exists() and not out.is_dir():
        raise RankGameError(f"--out {out} is a file, not a folder")
    if resume:
        if not path.is_file():
            raise RankGameError(f"no {SWEEP_FILE} in {out}: nothing to resume (drop --resume to start the sweep)")
        recorded = SweepSpec.from_json(json.loads(path.read_text())["grid"])
        if recorded != spec:
            raise RankGameError(
                f"the sweep in {out} has another grid; resume it with the same envs, methods, seeds, steps, "
                f"variants and options (recorded: {json.dumps(recorded.to_json())})"
            )
    elif path.exists():
        raise RankGameError(f"{out} already holds a sweep; pass --resume to continue it or choose another --out")


def write_grid(out: Path, spec: SweepSpec) -> None:
    """Record the grid and the command in ``out/sweep.json`` (atomically)."""
    payload = {"grid": spec.to_json(), "command": shlex.join(sys.argv)}
    atomic_write_bytes(out / SWEEP_FILE, json.dumps(payload, indent=2).encode())


def require_reachable(address: str, timeout_s: float = 5.0) -> None:
    """A one-line :class:`RankGameError` unless something listens at ``HOST:PORT`` (``auto`` is not checked)."""
    if address == "auto":
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        raise RankGameError(f"--address {address!r}: give HOST:PORT (the head node's, e.g. node1:6379) or auto")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise RankGameError(f"cannot reach a Ray cluster at {address}: {exc.strerror or exc}") from None


def run_sweep(
    spec: SweepSpec,
    out: str | Path,
    *,
    resume: bool = False,
    cores: int | None = None,
    address: str | None = None,
    storage: str | None = None,
    max_failures: int = 3,
    verbose: int = 1,
) -> dict[str, Any]:
    """Run every unfinished trial of ``spec`` on Ray Tune; returns ``{"trials": n, "ran": n, "skipped": n,
    "failed": [names]}``.

    Args:
        spec: the grid.
        out: the sweep folder (one run folder per trial, and ``sweep.json``).
        resume: continue the sweep in ``out`` (same grid); finished trials are skipped.
        cores: trials at once on this machine (default: its cores); ignored with ``address``.
        address: a running Ray cluster's address (``HOST:6379``, or ``auto``).
        storage: Ray's experiment state (default: ``out/.ray``).
        max_failures: restarts of a trial whose worker died.
        verbose: Ray's progress output (0 silent, 1 the progress table).
    Raises:
        RankGameError: a bad grid, trial, folder or address, before any trial starts.
    """
    out = Path(out).resolve()
    spec.validate()
    if address is not None:
        require_reachable(address)
    grid = trials(spec, out)
    check_trials(grid)
    check_grid(out, spec, resume)
    todo = [trial for trial in grid if not trial_finished(out / trial.name, trial.steps)]
    summary: dict[str, Any] = {"trials": len(grid), "ran": len(todo), "skipped": len(grid) - len(todo), "failed": []}
    _require_ray()
    if not resume:
        write_grid(out, spec)
    if todo:
        options = {"cores": cores, "address": address, "max_failures": max_failures, "verbose": verbose}
        summary["failed"] = launch_trials(todo, storage or str(out / ".ray"), **options)
    return summary
