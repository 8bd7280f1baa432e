"""Experiment tracking: a run's settings as TensorBoard hyperparameters, and Weights & Biases logging.

:func:`flat_settings` turns a run's nested JSON config into the flat ``section.option`` table both
trackers show. :func:`write_hparams` adds it to a TensorBoard writer (the HParams tab, with the
normalized score as the metric). :class:`WandbRun` logs a run to W&B (``rankgame train --wandb``, the
``wandb`` extra): the settings once, every evaluation row at its environment step, and the final policy
file as a model artifact. It runs offline unless ``WANDB_MODE`` says otherwise, writing under the run
folder (``OUT/wandb``), so no network is needed; ``wandb sync OUT/wandb/offline-run-*`` uploads it
later. The W&B run id is kept in ``OUT/wandb-run-id``, so a resumed run continues the same W&B run.
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from rankgame.atomic import atomic_write_bytes
from rankgame.errors import RankGameError

#: The file in a run folder that holds its W&B run id.
RUN_ID_NAME = "wandb-run-id"

#: The TensorBoard scalar the HParams tab ranks runs by.
HPARAM_METRIC = "normalized_score"

Setting = str | float | int | bool


def flat_settings(config: Mapping[str, Any], prefix: str = "") -> dict[str, Setting]:
    """``{"reward": {"lr": 1e-3}}`` as ``{"reward.lr": 1e-3}``: nested sections joined by dots, lists written
    as text (``"256 256"``), options that are None left out."""
    flat: dict[str, Setting] = {}
    for name, value in config.items():
        key = f"{prefix}{name}"
        if isinstance(value, Mapping):
            flat.update(flat_settings(value, f"{key}."))
        elif isinstance(value, list | tuple):
            flat[key] = " ".join(str(item) for item in value)
        elif value is not None:
            flat[key] = value if isinstance(value, bool | int | float) else str(value)
    return flat


def write_hparams(writer: Any, config: Mapping[str, Any]) -> None:
    """Record ``config`` (flattened) as the hyperparameters of a tensorboardX ``SummaryWriter``'s run, in
    its own event file, with :data:`HPARAM_METRIC` as the metric the HParams tab shows."""
    from tensorboardX.summary import hparams

    file_writer = writer._get_file_writer()  # the writer's own event file, not a new sub-run
    for summary in hparams(flat_settings(config), {HPARAM_METRIC: 0.0}):
        file_writer.add_summary(summary)


def require_wandb() -> Any:
    """The ``wandb`` module; a one-line :class:`RankGameError` if it is not installed."""
    try:
        import wandb
    except ImportError:
        raise RankGameError("--wandb needs Weights & Biases: pip install 'rankgame[wandb]'") from None
    return wandb


class WandbRun:
    """One run's W&B record (see the module docstring).

    Args:
        out: the run folder.
        config: the run's settings as JSON.
        name: the run's display name.

    Raises:
        RankGameError: the wandb package is not installed.
    """

    def __init__(self, out: Path, config: Mapping[str, Any], name: str) -> None:
        self._wandb = wandb = require_wandb()
        id_file = out / RUN_ID_NAME
        run_id = id_file.read_text().strip() if id_file.is_file() else uuid.uuid4().hex[:16]
        atomic_write_bytes(id_file, (run_id + "\n").encode())
        self.out = out
        self.run = wandb.init(
            project=os.environ.get("WANDB_PROJECT", "rankgame"),
            dir=str(out),
            name=name,
            id=run_id,
            resume="allow",
            config=flat_settings(config),
            mode=os.environ.get("WANDB_MODE", "offline"),
        )

    def log(self, row: Mapping[str, float | int]) -> None:
        """Log an evaluation row at its ``env_steps``, committed at once: W&B would otherwise hold a row
        given an explicit step until the next row or the end of the run, and lose it with a killed process."""
        step = int(row["env_steps"])
        self.run.log({key: value for key, value in row.items() if key != "env_steps"}, step=step, commit=True)

    def finish(self, policy: Path | None) -> None:
        """Attach the policy file (if the run saved one) as a model artifact and close the W&B run."""
        if policy is not None and policy.is_file():
            artifact = self._wandb.Artifact(f"policy-{self.run.id}", type="model")
            artifact.add_file(str(policy))
            self.run.log_artifact(artifact)
        self.run.finish()
