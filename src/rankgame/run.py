"""One run harness for ``rankgame train`` and ``rankgame expert``: the run folder, resume, logs, the
progress bar, the evaluation and checkpoint cadence, signals, and runs that never fail silently.

A :class:`Trainer` (the ranking game, the expert's SAC) says how to take one step, evaluate, save its
policies and checkpoint itself; :func:`run` does everything around it:

* the folder: a new run refuses a folder that holds one; ``--resume`` continues from the checkpoint
  (settings must match, :func:`~rankgame.checkpoint.require_same_settings`), or from step 0 if the
  run stopped before its first one; temporary files left by a killed write are removed;
* every ``eval_every`` steps: an evaluation row in ``metrics.csv`` (and TensorBoard), the trainer's
  policies, the progress bar's score, and the callback, which stops the run by returning False;
* every ``checkpoint_every`` steps (at the first step after it where the trainer can checkpoint) and
  at the last step: the checkpoint, with the last evaluation row, so that a finished run resumed
  reports it;
* SIGINT and SIGTERM stop the run after the step in progress with a checkpoint at that step and a
  :class:`~rankgame.errors.RunInterrupted` naming it (a second signal stops at once);
* a :class:`~rankgame.errors.NonFiniteError` (a loss, parameter or action that is NaN or infinite)
  stops the run with the step and the quantity; nothing non-finite is ever written, so the last
  checkpoint stays good and resumable; a write that fails (a full disk) names the file and says that
  the last checkpoint is intact.
"""

from __future__ import annotations

import json
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from tqdm import tqdm

from rankgame.atomic import atomic_write_bytes
from rankgame.checkpoint import (
    CHECKPOINT_NAME,
    RUN_CONTROL_OPTIONS,
    load_checkpoint,
    require_same_settings,
    save_checkpoint,
)
from rankgame.errors import NonFiniteError, RankGameError, RunInterrupted
from rankgame.logging import RunLogger

#: ``callback(step, row)`` is called after every evaluation; returning False stops the run.
Callback = Callable[[int, dict[str, float]], bool | None]

#: The actor of a run's last evaluation, in the run folder (``rankgame evaluate --policy``).
POLICY_NAME = "policy.msgpack"


class Trainer(Protocol):
    """What :func:`run` drives."""

    env_steps: int
    """Environment steps taken so far."""

    def step(self, step: int) -> None:
        """Take environment step number ``step`` and every update due after it."""

    def can_checkpoint(self, step: int) -> bool:
        """Whether a due checkpoint may be written after ``step`` (e.g. only at an iteration's end)."""

    def evaluate(self) -> dict[str, float]:
        """Evaluation columns of the metrics row (true return, normalized score, ...)."""

    def training_metrics(self) -> dict[str, float]:
        """The latest training metrics (losses), logged with every evaluation."""

    def save_policies(self, out: Path, step: int, row: dict[str, float]) -> None:
        """Write the policy files of this evaluation into the run folder ``out``."""

    def postfix(self, row: dict[str, float]) -> dict[str, str]:
        """Progress-bar fields of an evaluation row."""

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """JSON metadata and arrays that :meth:`restore` turns back into this trainer."""

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`checkpoint`."""


@dataclass(frozen=True)
class RunSettings:
    """How a run goes: its folder, length, cadence and display."""

    out: Path
    steps: int
    eval_every: int
    checkpoint_every: int
    resume: bool
    tensorboard: bool
    progress: bool
    description: str
    wandb: bool = False


@dataclass
class Resumed:
    """What a run continues from: the checkpoint's metadata and arrays (None when it starts at step 0)."""

    metadata: dict[str, Any] | None
    arrays: dict[str, np.ndarray]


def open_run(settings: RunSettings, config: dict[str, Any]) -> Resumed:
    """Check the run folder before anything is built.

    Without ``resume`` a folder that already holds a run is refused. With it, the checkpoint is read
    and its settings compared with ``config`` (a config as JSON); a run stopped before it wrote its
    first checkpoint starts again at step 0. A folder with no run in it is refused, since ``--resume``
    there most likely names the wrong folder.
    """
    out = settings.out
    if out.exists() and not out.is_dir():
        raise RankGameError(f"--out {out} is a file, not a folder")
    ckpt, started = out / CHECKPOINT_NAME, (out / "metrics.csv").exists()
    if not settings.resume:
        if started or ckpt.exists():
            raise RankGameError(f"{out} already holds a run; pass --resume to continue it or choose another --out")
        return Resumed(None, {})
    if not ckpt.exists():
        if not started:
            raise RankGameError(f"no checkpoint to resume from at {ckpt}")
        print(f"{out}: the run stopped before its first checkpoint; starting it again at step 0", file=sys.stderr)
        return Resumed(None, {})
    metadata, arrays = load_checkpoint(ckpt)
    require_same_settings(metadata["config"], config, RUN_CONTROL_OPTIONS)
    if settings.steps < int(metadata["env_steps"]):
        raise RankGameError(f"--steps {settings.steps} is below the checkpoint's {metadata['env_steps']} steps")
    return Resumed(metadata, arrays)


def _config_record(path: Path, command: str, config: dict[str, Any], resuming: bool) -> dict[str, Any]:
    """What ``config.json`` holds: the command that started the run, the commands that resumed it (in
    order, under ``resumed_with``) and the settings. A resumed run keeps the first command it was
    started with, so the archived record names the command that reproduces it."""
    previous: dict[str, Any] = {}
    if resuming and path.is_file():
        try:
            previous = json.loads(path.read_text())
        except (OSError, ValueError):
            previous = {}
    if not isinstance(previous, dict) or not isinstance(previous.get("command"), str):
        return {"command": command, **config}
    resumes = [c for c in previous.get("resumed_with", []) if isinstance(c, str)]
    return {"command": previous["command"], "resumed_with": [*resumes, command], **config}


def run(
    trainer: Trainer,
    settings: RunSettings,
    resumed: Resumed,
    config: dict[str, Any],
    columns: tuple[str, ...],
    command: str,
    callback: Callback | None = None,
) -> dict[str, Any]:
    """Run ``trainer`` to ``settings.steps`` (see the module docstring); returns the last evaluation row
    with ``env_steps`` and ``stopped_early``."""
    out = settings.out
    _make_out_dir(out)
    for stale in out.glob(".*.tmp"):  # left by a write that was killed
        stale.unlink(missing_ok=True)
    clock = _Clock()
    last_row: dict[str, float] = {}
    last_saved = 0
    if resumed.metadata is not None:
        trainer.restore(resumed.metadata, resumed.arrays)
        clock.restore(resumed.metadata)
        last_row, last_saved = dict(resumed.metadata.get("last_row", {})), trainer.env_steps
    with _writing(out / "config.json", out, last_saved):
        record = _config_record(out / "config.json", command, config, resuming=resumed.metadata is not None)
        atomic_write_bytes(out / "config.json", json.dumps(record, indent=2).encode())
    with _writing(out / "metrics.csv", out, last_saved):
        resume_step = trainer.env_steps if settings.resume else None
        logger = RunLogger(out, columns, settings.tensorboard, resume_step=resume_step, hparams=config)
    tracker = None
    if settings.wandb:
        from rankgame.tracking import WandbRun

        tracker = WandbRun(out, config, settings.description)
    bar = tqdm(
        total=settings.steps,
        initial=trainer.env_steps,
        disable=not settings.progress,
        unit="step",
        dynamic_ncols=True,
        desc=settings.description,
    )
    stopped_early, checkpoint_due, step = False, False, trainer.env_steps

    def save() -> None:
        nonlocal last_saved
        metadata, arrays = trainer.checkpoint()
        metadata = {**metadata, **clock.state(), "config": config, "last_row": last_row}
        with _writing(out / CHECKPOINT_NAME, out, last_saved):
            save_checkpoint(out / CHECKPOINT_NAME, metadata, arrays)
        last_saved = step

    try:
        with _stop_signals() as signals:
            for step in range(trainer.env_steps + 1, settings.steps + 1):
                trainer.step(step)
                keep_going = True
                if step % settings.eval_every == 0 or step == settings.steps:
                    last_row = {"env_steps": step, **clock.evaluation(step, trainer.evaluate)}
                    last_row.update(trainer.training_metrics())
                    with _writing(out / "metrics.csv", out, last_saved):
                        logger.log(last_row)
                    if tracker is not None:
                        tracker.log(last_row)
                    with _writing(out, out, last_saved):
                        trainer.save_policies(out, step, last_row)
                    bar.set_postfix(trainer.postfix(last_row))
                    keep_going = callback is None or callback(step, dict(last_row)) is not False
                checkpoint_due = checkpoint_due or step % settings.checkpoint_every == 0
                stopping = signals.received is not None or not keep_going
                if (checkpoint_due and trainer.can_checkpoint(step)) or step == settings.steps or stopping:
                    save()
                    checkpoint_due = False
                bar.update(1)
                if signals.received is not None:
                    name = signal.Signals(signals.received).name
                    raise RunInterrupted(
                        f"stopped by {name} at step {step}; {out / CHECKPOINT_NAME} holds it: --resume continues "
                        f"from step {step}",
                        signals.received,
                    )
                if not keep_going:
                    stopped_early = True
                    break
    except NonFiniteError as exc:
        raise RankGameError(f"step {step}: {exc}; {_last_good(out, last_saved)}") from None
    except KeyboardInterrupt:
        raise RunInterrupted(f"interrupted at step {step}; {_last_good(out, last_saved)}", signal.SIGINT) from None
    finally:
        bar.close()
        logger.close()
        if tracker is not None:
            tracker.finish(out / POLICY_NAME)
    return {**last_row, "env_steps": trainer.env_steps, "stopped_early": stopped_early}


class _Clock:
    """Wall-clock seconds of the whole run and of its evaluations, carried across resumes."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.eval_s = 0.0

    def restore(self, metadata: dict[str, Any]) -> None:
        self.start = time.perf_counter() - float(metadata["wall_s"])
        self.eval_s = float(metadata["eval_s"])

    def state(self) -> dict[str, float]:
        return {"wall_s": time.perf_counter() - self.start, "eval_s": self.eval_s}

    def evaluation(self, step: int, evaluate: Callable[[], dict[str, float]]) -> dict[str, float]:
        """``evaluate()`` with the time columns: ``wall_s`` and training-only ``steps_per_s``."""
        eval_start = time.perf_counter()
        result = evaluate()
        self.eval_s += time.perf_counter() - eval_start
        wall = time.perf_counter() - self.start
        return {"wall_s": wall, "steps_per_s": step / max(wall - self.eval_s, 1e-9), **result}


class _Signals:
    received: int | None = None


@contextmanager
def _stop_signals() -> Iterator[_Signals]:
    """While inside, SIGINT and SIGTERM only set ``received`` (a second one interrupts at once); outside
    the main thread, where handlers cannot be installed, signals keep their usual effect."""
    signals = _Signals()
    if threading.current_thread() is not threading.main_thread():
        yield signals
        return

    def handler(signum: int, _frame: Any) -> None:
        if signals.received is not None:
            raise KeyboardInterrupt
        signals.received = signum

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield signals
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def _last_good(out: Path, step: int) -> str:
    if step == 0:
        return "no checkpoint was written yet"
    return f"the last good checkpoint ({out / CHECKPOINT_NAME}, step {step}) is intact and resumable"


@contextmanager
def _writing(path: Path, out: Path, last_saved: int) -> Iterator[None]:
    """A write to ``path`` whose failure (a full disk, permissions) is reported in one line that says
    whether the run folder ``out`` holds a good checkpoint."""
    try:
        yield
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise RankGameError(f"cannot write {exc.filename or path}: {reason}; {_last_good(out, last_saved)}") from None


def _make_out_dir(out: Path) -> None:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RankGameError(f"cannot create the output folder {out}: {exc.strerror}") from None


def finite_or_none(row: dict[str, Any]) -> dict[str, Any]:
    """``row`` with NaN and infinite floats as None, so that it prints as valid JSON."""
    return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in row.items()}
