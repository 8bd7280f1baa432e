"""Results pages from run folders (``rankgame report``): a Markdown page and its figures.

:func:`write_report` reads run folders (each with ``config.json`` and ``metrics.csv``, as
``rankgame train`` writes them and the archives under ``benchmarks/results/`` keep them) and writes
``OUT/results.md`` with figures in ``OUT/img/``. Every number on the page is computed from the runs,
except the published figures placed beside them, which come from :mod:`rankgame.data.published`.

Which runs: a folder named on the command line that holds ``metrics.csv`` is one run; any other
folder stands for every folder below it that holds ``metrics.csv`` (a sweep or an archive folder; the
search does not descend into a run folder).

Groups: runs are grouped by (task, method, variant). The task, method and seed are the ``env``,
``method`` and ``seed`` of the run's ``config.json``. The variant is the folder that holds the run,
written from the folder named on the command line: for a named run folder it is the name of its
parent (``benchmarks/results/sample-efficiency/Hopper-v5__rank-pal-auto__s0`` is in
``sample-efficiency``), for a run found inside a named folder it is that folder's name followed by the
subfolders down to the run's parent (``nonstationary/backward``). So archives of different settings
(``sample-efficiency`` and ``sample-efficiency-hopper-k-1``) stay apart. A trial of a ``rankgame
sweep`` with variants, a folder named ``ENV__METHOD__sSEED__LABEL`` (its ``config.json``'s env, method
and seed, then the label), adds ``/LABEL`` to that (``my-sweep/reward.lr=1e-4``), so the variants
of one sweep folder stay apart too.

Seeds: seeds of :data:`HELD_OUT_SEED` (100) and up are held-out seeds, run once settings were chosen;
lower seeds are tuning seeds. Every cell and group says which it holds (``tuning``, ``held-out``, or
``mixed``).

Runs of ``rankgame expert`` (SAC on the task's true reward, the reference a learned reward is measured
against) are read too: their method is :data:`SAC_TRUE_REWARD`, and their ``eval_return`` is normalized
with the task's shipped expert data, as ``rankgame train`` normalizes its own.

Scores are the ``normalized_score`` column (0 random, 100 expert). A score "at 100k" is the
evaluation logged at exactly 100000 environment steps; a run without one is left out of that cell.
"""

from __future__ import annotations

import io
import json
import math
import re
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from rankgame.atomic import atomic_write_bytes
from rankgame.claims import CLAIMS, Metric, Side, judge
from rankgame.data.published import RELEASED_CURVES, TABLE1
from rankgame.errors import RankGameError
from rankgame.game.methods import OWN_TRAINER_METHODS
from rankgame.game.selection import selected_evaluation
from rankgame.plot import pyplot, read_curve
from rankgame.stats import (
    Interval,
    iqm,
    mean_and_sample_std,
    performance_profile,
    probability_of_improvement,
    stratified_bootstrap_ci,
)

#: Seeds from this one up are held-out seeds; lower seeds are tuning seeds.
HELD_OUT_SEED = 100
#: The keys every run's ``config.json`` must hold.
CONFIG_KEYS = ("command", "env", "method", "seed", "steps")
#: The ``metrics.csv`` column the page reports.
SCORE_COLUMN = "normalized_score"
#: The method of a ``rankgame expert`` run: SAC on the task's true reward.
SAC_TRUE_REWARD = "sac (true reward)"
#: Methods that never act in the environment: their ``env_steps`` are gradient steps.
GRADIENT_STEP_METHODS = tuple(name for name, trainer in OWN_TRAINER_METHODS.items() if not trainer.acts)
#: What a ``rankgame expert`` run's ``config.json`` records instead of a method.
EXPERT_RUN_KEYS = ("trajectories", "sac")
#: The success rate's column (Pen, Door), read for the claims.
SUCCESS_COLUMN = "eval_success"
#: The page's file name inside the output folder, and the figures' folder.
PAGE_NAME = "results.md"
IMAGE_FOLDER = "img"
#: The paper's tasks in the order of its Table 1; other tasks follow in alphabetical order.
PAPER_TASKS = tuple(dict.fromkeys(task for scores in TABLE1.values() for task in scores))


@dataclass(frozen=True, eq=False)
class Run:
    """One run folder: where it is, its group, and its normalized score at each evaluation."""

    folder: Path
    variant: str
    env: str
    method: str
    seed: int
    planned_steps: int
    command: str
    steps: np.ndarray = field(repr=False)
    """Environment steps of the evaluations ``(E,)``, increasing."""
    scores: np.ndarray = field(repr=False)
    """Normalized score of each evaluation ``(E,)``."""
    success: dict[int, float] = field(default_factory=dict, repr=False)
    """Success rate by environment step, on tasks that report one (``eval_success``)."""
    selected: float | None = None
    """Score of the evaluation whose policy the run selected by its learned reward
    (:mod:`rankgame.game.selection`); None for runs that select none."""

    def score_at(self, step: int) -> float | None:
        """The score of the evaluation logged at exactly ``step`` environment steps; None if none was."""
        hits = np.flatnonzero(self.steps == step)
        return float(self.scores[hits[-1]]) if len(hits) else None


class GroupKey(NamedTuple):
    """What a group of runs shares: its task, method and variant (see the module docstring)."""

    env: str
    method: str
    variant: str


class Row(NamedTuple):
    """A (method, variant): one row of the tables across tasks."""

    method: str
    variant: str

    @property
    def label(self) -> str:
        return f"{self.method} · {self.variant}"


# --------------------------------------------------------------------------------------------- reading


def find_run_folders(paths: Sequence[Path]) -> list[tuple[Path, str]]:
    """``(run folder, variant)`` of every run the named ``paths`` stand for, in order, each run once.

    A path holding ``metrics.csv`` is a run (its variant: its parent's name); any other folder stands for
    the folders below it holding ``metrics.csv`` (variant: the named folder's name and the subfolders to
    the run's parent). A path that is neither raises :class:`RankGameError` naming it.
    """
    found: dict[Path, tuple[Path, str]] = {}
    for path in map(Path, paths):
        if not path.is_dir():
            raise RankGameError(f"{path} is not a folder (give run folders, or folders that hold them)")
        if (path / "metrics.csv").is_file():
            found.setdefault(path.resolve(), (path, path.resolve().parent.name))
            continue
        runs = sorted(metrics.parent for metrics in path.rglob("metrics.csv") if metrics.is_file())
        run_set = set(runs)
        runs = [run for run in runs if not any(parent in run_set for parent in run.parents)]
        if not runs:
            raise RankGameError(f"{path} holds no metrics.csv and no run folders with one")
        for run in runs:
            variant = "/".join([path.resolve().name, *run.relative_to(path).parent.parts])
            found.setdefault(run.resolve(), (run, variant))
    return list(found.values())


def true_reward_curve(folder: Path, env: str) -> tuple[list[int], list[float]]:
    """Steps and normalized scores of a ``rankgame expert`` run: its ``eval_return`` normalized with the
    shipped expert data of ``env`` (random 0, expert 100)."""
    from rankgame.data.experts import load_shipped_expert, normalized_score, shipped_envs

    if env not in shipped_envs():
        raise RankGameError(f"{folder}: no shipped expert data of {env} to normalize its true returns with")
    expert = load_shipped_expert(env)
    steps, returns = read_curve(folder, "eval_return")
    random_return = float(expert.metadata["random_return_mean"])
    expert_return = float(expert.returns.mean())
    return steps, [float(normalized_score(ret, expert_return, random_return)) for ret in returns]


def read_run(folder: Path, variant: str) -> Run:
    """The :class:`Run` in ``folder`` (its ``config.json`` and the scores of its ``metrics.csv``)."""
    path = folder / "config.json"
    if not path.is_file():
        raise RankGameError(f"{folder}: no config.json (a run folder of rankgame train has one)")
    try:
        config = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise RankGameError(f"{path}: unreadable run settings ({exc})") from None
    expert_run = isinstance(config, dict) and "method" not in config and all(key in config for key in EXPERT_RUN_KEYS)
    if expert_run:
        config = {**config, "method": SAC_TRUE_REWARD}
    missing = [key for key in CONFIG_KEYS if not isinstance(config, dict) or key not in config]
    if missing:
        raise RankGameError(f"{path} has no {', '.join(missing)} (a run of rankgame train records them)")
    try:
        seed, planned = int(config["seed"]), int(config["steps"])
    except (TypeError, ValueError):
        raise RankGameError(f"{path}: seed and steps must be integers") from None
    env, method = str(config["env"]), str(config["method"])
    steps, scores = true_reward_curve(folder, env) if expert_run else read_curve(folder, SCORE_COLUMN)
    try:
        success = dict(zip(*read_curve(folder, SUCCESS_COLUMN), strict=True))
    except RankGameError:  # a task without success
        success = {}
    order = np.argsort(steps, kind="stable")
    # A trial of a rankgame sweep with variants is named ENV__METHOD__sSEED__LABEL: its variant gets /LABEL.
    trial = f"{env.replace('/', '__')}__{method}__s{seed}__"
    name = folder.resolve().name
    if name.startswith(trial) and len(name) > len(trial):
        variant = f"{variant}/{name[len(trial) :]}"
    return Run(
        folder=folder,
        variant=variant,
        env=env,
        method=method,
        seed=seed,
        planned_steps=planned,
        command=str(config["command"]),
        steps=np.asarray(steps, np.int64)[order],
        scores=np.asarray(scores, np.float64)[order],
        success=success,
        selected=_selected_score(folder, config),
    )


def _selected_score(folder: Path, config: dict[str, Any]) -> float | None:
    """The score of the run's selected evaluation (after its switch, if any), or None."""
    switch = config.get("switch")
    since = int(switch.get("at") or 0) if isinstance(switch, dict) else 0
    selected = selected_evaluation(folder, since)
    return None if selected is None else selected.normalized_score


def load_runs(paths: Sequence[Path]) -> list[Run]:
    """Every run the ``paths`` stand for (see :func:`find_run_folders`), read."""
    return [read_run(folder, variant) for folder, variant in find_run_folders(paths)]


def group_runs(runs: Iterable[Run]) -> dict[GroupKey, list[Run]]:
    """Runs by (task, method, variant), groups in :func:`task_order` then method and variant order, runs by
    seed."""
    groups: dict[GroupKey, list[Run]] = {}
    for run in runs:
        groups.setdefault(GroupKey(run.env, run.method, run.variant), []).append(run)
    rank = {env: i for i, env in enumerate(task_order(key.env for key in groups))}
    return {
        key: sorted(groups[key], key=lambda run: run.seed)
        for key in sorted(groups, key=lambda key: (rank[key.env], key.method, key.variant))
    }


# ------------------------------------------------------------------------------------------ published


def published_task(env: str) -> str:
    """The task whose published figures apply to ``env``: itself, or for a variant observed as the paper's
    gym -v2 task was (``rankgame/AntNoContact-v5``) its source task."""
    if env in PAPER_TASKS or not env.startswith("rankgame/"):
        return env
    from rankgame.envs.variants import OBS_PREFIX_VARIANTS

    return OBS_PREFIX_VARIANTS.get(env, (env, 0))[0]


def task_order(envs: Iterable[str]) -> list[str]:
    """The distinct ``envs``: the paper's tasks in its Table 1 order (a variant after its source task), then
    the others alphabetically."""
    paper = {task: i for i, task in enumerate(PAPER_TASKS)}
    return sorted(set(envs), key=lambda env: (paper.get(published_task(env), len(paper)), env))


def paper_figure(method: str, env: str) -> tuple[float, float] | None:
    """``(mean, std)`` of ``method`` on ``env`` in the paper's Table 1 (2M steps, 5 seeds); None if absent."""
    return TABLE1.get(method, {}).get(published_task(env))


def released_figure(method: str, env: str, step: int) -> float | None:
    """The authors' released curve of ``method`` on ``env`` at ``step``; None if it is not published."""
    return RELEASED_CURVES.get(method, {}).get(published_task(env), {}).get(step)


# ------------------------------------------------------------------------------------------- numbers


def seed_kind(seeds: Iterable[int]) -> str:
    """``"held-out"`` if every seed is >= :data:`HELD_OUT_SEED`, ``"tuning"`` if every seed is below it, else
    ``"mixed"``."""
    held_out = {seed >= HELD_OUT_SEED for seed in seeds}
    return "mixed" if len(held_out) > 1 else "held-out" if held_out == {True} else "tuning"


def steps_text(step: int) -> str:
    """``300000`` as ``300k``, ``2000000`` as ``2M``; other counts as they are."""
    if step and step % 1_000_000 == 0:
        return f"{step // 1_000_000}M"
    return f"{step // 1000}k" if step and step % 1000 == 0 else str(step)


def _num(value: float) -> str:
    return f"{value:.1f}"


def _count(n: int, noun: str) -> str:
    """``1 run``, ``3 runs``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def cell_text(scores: Sequence[float], seeds: Sequence[int]) -> str:
    """A table cell: ``mean ± sample std (n, seed kind)``, the mean alone for one run, ``-`` for none."""
    if not scores:
        return "-"
    mean, std = mean_and_sample_std(scores)
    spread = "" if std is None else f" ± {_num(std)}"
    return f"{_num(mean)}{spread} ({len(scores)}, {seed_kind(seeds)})"


def at_step(runs: Sequence[Run], step: int) -> tuple[list[float], list[int]]:
    """Scores and seeds of the ``runs`` that logged an evaluation at exactly ``step``."""
    pairs = [(score, run.seed) for run in runs if (score := run.score_at(step)) is not None]
    return [score for score, _ in pairs], [seed for _, seed in pairs]


def shared_horizon(runs: Sequence[Run]) -> int | None:
    """The last evaluation step that every one of ``runs`` logged; None if they share none."""
    common = set.intersection(*(set(run.steps.tolist()) for run in runs))
    return max(common) if common else None


def collapse_counts(scores: Sequence[float], reach: float, below: float) -> tuple[int, int] | None:
    """``(evaluations after the first one at reach or more, how many of them are below below)``; None for a
    run that never reaches ``reach``. ``scores``: ``(E,)`` in step order."""
    first = next((i for i, score in enumerate(scores) if score >= reach), None)
    if first is None:
        return None
    later = scores[first + 1 :]
    return len(later), int(sum(score < below for score in later))


@dataclass(frozen=True)
class Stability:
    """How a group's runs held up after first reaching ``reach`` (pooled over its runs)."""

    runs: int
    never_reached: tuple[int, ...]
    """Seeds of the runs that never reached ``reach``."""
    after: int
    """Evaluations after each run's first at ``reach`` or more, summed over the runs that reached it."""
    collapsed: int
    """How many of those are below ``below``."""
    final: float
    """Mean over the runs of each run's last evaluation."""
    best: float
    """Mean over the runs of each run's best evaluation."""
    selected: tuple[float, ...] = ()
    """Score of each run's selected evaluation, for the runs that select one."""
    final_below: int = 0
    """How many runs' last evaluations are below ``below``: a collapsed policy handed over."""
    selected_below: int = 0
    """How many of :attr:`selected` are below ``below``."""

    @property
    def handed_over_text(self) -> str:
        """Runs whose last and whose selected evaluations are below ``below``, ``1/5 · 0/5``."""
        selected = f"{self.selected_below}/{len(self.selected)}" if self.selected else "-"
        return f"{self.final_below}/{self.runs} · {selected}"

    @property
    def selected_text(self) -> str:
        """Mean of :attr:`selected`, with the count of runs when not every run selects; ``-`` for none."""
        if not self.selected:
            return "-"
        mean = _num(float(np.mean(self.selected)))
        return mean if len(self.selected) == self.runs else f"{mean} ({len(self.selected)} runs)"

    @property
    def share_text(self) -> str:
        """``collapsed/after = share%``, ``-`` without later evaluations."""
        return f"{self.collapsed}/{self.after} = {100 * self.collapsed / self.after:.1f}%" if self.after else "-"


def stability(runs: Sequence[Run], reach: float = 80.0, below: float = 50.0) -> Stability:
    """The :class:`Stability` of a group of runs."""
    counts = [collapse_counts(run.scores.tolist(), reach, below) for run in runs]
    reached = [c for c in counts if c is not None]
    selected = tuple(run.selected for run in runs if run.selected is not None)
    return Stability(
        runs=len(runs),
        never_reached=tuple(run.seed for run, c in zip(runs, counts, strict=True) if c is None),
        after=sum(c[0] for c in reached),
        collapsed=sum(c[1] for c in reached),
        final=float(np.mean([run.scores[-1] for run in runs])),
        best=float(np.mean([run.scores.max() for run in runs])),
        selected=selected,
        final_below=sum(run.scores[-1] < below for run in runs),
        selected_below=sum(score < below for score in selected),
    )


def pooled_iqm(scores_by_task: Sequence[np.ndarray], n_boot: int, seed: int) -> Interval:
    """IQM of every run of every task pooled, with its stratified-bootstrap 95% interval."""
    return stratified_bootstrap_ci(
        scores_by_task,
        lambda tasks: iqm(np.concatenate(tasks, axis=-1), axis=-1),
        n_boot=n_boot,
        seed=seed,
        vectorized=True,
    )


def mean_band(table: np.ndarray, n_boot: int, seed: int, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Percentile bootstrap interval ``(low (S,), high (S,))`` of the mean over runs at each step of
    ``table`` ``(n runs, S steps)``, resampling runs with replacement (the same runs at every step)."""
    rng = np.random.default_rng(seed)
    means = table[rng.integers(0, len(table), size=(n_boot, len(table)))].mean(axis=1)  # (B, S)
    low, high = np.quantile(means, [(1 - level) / 2, (1 + level) / 2], axis=0)
    return low, high


# -------------------------------------------------------------------------------------------- figures


def _png(fig: Any) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return buffer.getvalue()


def curves_figure(env: str, groups: dict[GroupKey, list[Run]], n_boot: int, seed: int) -> bytes:
    """PNG of the learning curves of every group of ``env``: the mean over seeds at the steps all of a
    group's runs logged, with a bootstrap 95% band of that mean (none for a single run)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, runs in groups.items():
        common = sorted(set.intersection(*(set(run.steps.tolist()) for run in runs)))
        table = np.array([[run.score_at(step) for step in common] for run in runs], np.float64)
        label = f"{key.method} · {key.variant} ({_count(len(runs), 'seed')}, {seed_kind(r.seed for r in runs)})"
        if key.method in GRADIENT_STEP_METHODS:
            label += ", x: gradient steps"
        (line,) = ax.plot(common, table.mean(axis=0), label=label)
        if len(runs) > 1:
            low, high = mean_band(table, n_boot, seed)
            ax.fill_between(common, low, high, color=line.get_color(), alpha=0.2)
    ax.set_title(f"{env}: mean over seeds, bootstrap 95% band")
    ax.set_xlabel("environment steps")
    ax.set_ylabel("normalized score")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _png(fig)


def profile_figure(pooled: dict[int, dict[Row, np.ndarray]]) -> bytes:
    """PNG of the performance profiles, one panel per step: the fraction of runs (all tasks pooled) whose
    normalized score is above each threshold, one line per (method, variant). ``pooled[step][row]``:
    the scores ``(n,)`` of the row's runs at that step."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(pooled), figsize=(5.5 * len(pooled), 4), squeeze=False)
    everything = np.concatenate([scores for rows in pooled.values() for scores in rows.values()] or [np.zeros(1)])
    thresholds = np.linspace(min(0.0, everything.min()), max(100.0, everything.max()) + 5.0, 400)
    for ax, (step, rows) in zip(axes[0], pooled.items(), strict=True):
        for row, scores in rows.items():
            ax.step(
                thresholds, performance_profile(scores, thresholds), where="post", label=f"{row.label} ({len(scores)})"
            )
        ax.set_title(f"at {steps_text(step)} steps")
        ax.set_xlabel("normalized score threshold τ")
        ax.set_ylabel("fraction of runs with score > τ")
        ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        if rows:
            ax.legend(fontsize=7)
    fig.tight_layout()
    return _png(fig)


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", text)


# ----------------------------------------------------------------------------------------------- page


def _md(text: object) -> str:
    """Text safe inside a Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> list[str]:
    lines = ["| " + " | ".join(map(_md, header)) + " |", "|" + " --- |" * len(header)]
    return lines + ["| " + " | ".join(map(_md, row)) + " |" for row in rows]


def _interval_text(interval: Interval, digits: int = 1) -> str:
    return f"{interval.estimate:.{digits}f} [{interval.low:.{digits}f}, {interval.high:.{digits}f}]"


def _published_rows(methods: Sequence[str], tasks: Sequence[str], step: int | None) -> list[list[str]]:
    """Reference rows of a headline table: the authors' released curve at ``step`` (if published) and the
    paper's Table 1 at 2M, for each method that has a figure for one of ``tasks``."""
    rows = []
    for method in methods:
        if step is not None:
            curve = [released_figure(method, task, step) for task in tasks]
            if any(value is not None for value in curve):
                label = f"*authors' released LfO curve at {steps_text(step)} (moving average of 20 evaluations)*"
                rows.append([method, label, *("-" if v is None else f"{v:g}" for v in curve)])
        paper = [paper_figure(method, task) for task in tasks]
        if any(value is not None for value in paper):
            label = "*paper, Table 1 (LfO) at 2M (mean ± std, 5 seeds)*"
            rows.append([method, label, *("-" if v is None else f"{v[0]:g} ± {v[1]:g}" for v in paper)])
    return rows


class _Page:
    """The page's Markdown lines and figures, built in memory before anything is written."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.figures: dict[str, bytes] = {}

    def add(self, *lines: str) -> None:
        self.lines.extend(lines)

    def figure(self, name: str, make: Callable[[], bytes], alt: str) -> None:
        self.figures[name] = make()
        self.add(f"![{alt}]({IMAGE_FOLDER}/{name})", "")


def claims_section(groups: dict[GroupKey, list[Run]], reach: float, below: float) -> list[str]:
    """The claims table (:data:`rankgame.claims.CLAIMS`): each claim, the paper's figure, ours from ``groups``
    and the verdict."""

    def members(side: Side, env: str) -> list[Run]:
        if side.variant is not None:
            return groups.get(GroupKey(env, side.method, side.variant), [])
        matching = [runs for key, runs in groups.items() if key.env == env and key.method == side.method]
        return max(matching, key=len, default=[])

    def values_at(side: Side, env: str, step: int, metric: Metric) -> list[float]:
        runs = members(side, env)
        found = [run.score_at(step) for run in runs] if metric == "score" else [run.success.get(step) for run in runs]
        return [value for value in found if value is not None]

    def collapses(side: Side, env: str) -> tuple[int, int] | None:
        runs = members(side, env)
        result = stability(runs, reach, below) if runs else None
        return None if result is None else (result.collapsed, result.after)

    body = []
    for claim in CLAIMS:
        measured, verdict = judge(claim, values_at, collapses)
        body.append([claim.statement, claim.source, claim.paper, measured, f"**{verdict}**"])
    intro = (
        "Each claim is tested by comparisons of groups of runs (`rankgame.claims`): higher mean normalized "
        "score (success rate on Pen and Door) at the step named, or for stability a smaller share of evaluations below "
        f"{below:g} after first reaching {reach:g}. Verdict: reproduced when every comparison with runs on "
        "both sides holds, not reproduced when one does not, not run when none has runs. Means over few seeds "
        "decide, so each figure gives the sample standard deviation and the number of runs (n): where the gap "
        "between the means is smaller than the spread, a verdict is not a significant margin."
    )
    header = ["claim", "where", "paper", "ours (A vs B)", "verdict"]
    return ["## Claims of the paper", "", intro, "", *_table(header, body), ""]


def build_page(
    runs: Sequence[Run],
    at: Sequence[int],
    n_boot: int,
    seed: int,
    reach: float,
    below: float,
    claim_runs: Sequence[Run] = (),
) -> tuple[str, dict[str, bytes]]:
    """The Markdown text of the page and its figures (name in ``img/`` -> PNG bytes); ``claim_runs`` are read
    for the claims table only."""
    groups = group_runs(runs)
    tasks = task_order(run.env for run in runs)
    rows = sorted({Row(key.method, key.variant) for key in groups})
    methods = sorted({row.method for row in rows})
    cell = {(Row(k.method, k.variant), k.env): members for k, members in groups.items()}
    page = _Page()
    every_seed = [run.seed for run in runs]
    page.add(
        "# Results",
        "",
        f"Generated by `rankgame report` from {_count(len(runs), 'run folder')} ({_count(len(groups), 'group')} "
        f"of task, method and variant; seeds: {seed_kind(every_seed)}). Every figure of ours is computed from "
        f"the runs' `metrics.csv` ({SCORE_COLUMN}: 0 is the random policy, 100 the expert) and `config.json`; the "
        "published figures beside them come from `rankgame.data.published`.",
        "",
        f"* Seeds below {HELD_OUT_SEED} are **tuning** seeds, seeds of {HELD_OUT_SEED} and up **held-out** "
        "seeds; every cell and group says which it holds (`mixed`: some of each).",
        "* A variant is the folder that holds the runs (an archive folder such as `sample-efficiency`, or a "
        "sweep); runs are grouped by task, method and variant.",
        "* Cells: `mean ± sample std (n runs, seeds)` of the evaluation logged at exactly that step; runs "
        "without one are left out.",
        f"* Intervals are percentile bootstrap 95% intervals ({n_boot} samples, seed {seed}), resampling runs "
        "within each task.",
        "",
    )
    page.add(*claims_section(group_runs([*runs, *claim_runs]), reach, below))

    # Headline tables.
    header = ["method", "variant", *tasks]
    for step in at:
        page.add(f"## Normalized score at {steps_text(step)} steps", "")
        body = [
            [row.method, row.variant, *(cell_text(*at_step(cell.get((row, task), []), step)) for task in tasks)]
            for row in rows
        ]
        page.add(*_table(header, body + _published_rows(methods, tasks, step)), "")
    page.add(
        "## Normalized score at the longest horizon each cell's runs share",
        "",
        "Each cell is read at the last evaluation step that all of its runs logged, named after `at`."
        + "".join(
            f" For `{method}`, which never acts in the environment, a step is a gradient step."
            for method in GRADIENT_STEP_METHODS
            if method in methods
        ),
        "",
    )
    body = []
    for row in rows:
        texts = []
        for task in tasks:
            members = cell.get((row, task), [])
            horizon = shared_horizon(members) if members else None
            if horizon is None:
                texts.append("-")
            else:
                texts.append(f"{cell_text(*at_step(members, horizon))} at {steps_text(horizon)}")
        body.append([row.method, row.variant, *texts])
    page.add(*_table(header, body + _published_rows(methods, tasks, None)), "")

    # Aggregates across tasks.
    page.add(
        "## Aggregates across tasks",
        "",
        "### Interquartile mean (IQM) of the normalized score",
        "",
        "The IQM pools every run of every task of a row (a task with more runs weighs more) and averages the "
        "middle 50% of their scores (fractional weights at the quartiles, `rankgame.stats.iqm`). Rows cover "
        "different tasks where they ran different tasks: compare rows of the same tasks.",
        "",
    )
    pooled: dict[int, dict[Row, np.ndarray]] = {step: {} for step in at}
    by_task: dict[int, dict[Row, dict[str, np.ndarray]]] = {step: {} for step in at}
    iqm_body = []
    for row in rows:
        texts = []
        for step in at:
            per_task = {}
            seeds = []
            for task in tasks:
                scores, task_seeds = at_step(cell.get((row, task), []), step)
                if scores:
                    per_task[task] = np.asarray(scores)
                    seeds += task_seeds
            by_task[step][row] = per_task
            if not per_task:
                texts.append("-")
                continue
            pooled[step][row] = np.concatenate(list(per_task.values()))
            estimate = pooled_iqm(list(per_task.values()), n_boot, seed)
            texts.append(
                f"{_interval_text(estimate)} ({_count(len(seeds), 'run')}, {_count(len(per_task), 'task')}, "
                f"{seed_kind(seeds)})"
            )
        row_tasks = [task for task in tasks if (row, task) in cell]
        iqm_body.append([row.method, row.variant, *texts, ", ".join(row_tasks)])
    iqm_header = ["method", "variant", *(f"IQM at {steps_text(step)} [95% CI]" for step in at), "tasks"]
    page.add(*_table(iqm_header, iqm_body), "")

    for step in at:
        page.add(
            f"### Probability of improvement at {steps_text(step)} steps",
            "",
            "P(row > column): the chance that a run of the row beats a run of the column on the same task "
            "(ties count half), over all pairs of their runs, averaged over the tasks both have at this step, "
            "with a stratified-bootstrap 95% interval; 0.5 is no difference.",
            "",
        )
        present = [row for row in rows if by_task[step][row]]
        body = []
        for x in present:
            texts = []
            for y in present:
                shared = [task for task in by_task[step][x] if task in by_task[step][y]]
                if x == y or not shared:
                    texts.append("—" if x == y else "- (no shared task)")
                    continue
                interval = probability_of_improvement(
                    [by_task[step][x][task] for task in shared],
                    [by_task[step][y][task] for task in shared],
                    n_boot=n_boot,
                    seed=seed,
                )
                texts.append(f"{_interval_text(interval, 2)} ({_count(len(shared), 'task')})")
            body.append([x.label, *texts])
        page.add(*(_table(["P(row > column)", *(y.label for y in present)], body) if present else ["No runs."]), "")

    page.add(
        "### Performance profiles",
        "",
        "Fraction of runs (every task pooled) whose normalized score at the step is above each threshold τ; "
        "the legend gives the number of runs.",
        "",
    )
    page.figure("performance_profile.png", lambda: profile_figure(pooled), "performance profiles")

    # Learning curves.
    page.add(
        "## Learning curves",
        "",
        "Mean normalized score over a group's seeds at the evaluation steps all of them logged, with a "
        "bootstrap 95% band of the mean (resampling seeds; none for a single seed); one line per method and "
        "variant.",
        "",
    )
    for task in tasks:
        task_groups = {key: members for key, members in groups.items() if key.env == task}
        page.add(f"### {task}", "")
        page.figure(f"curves_{_slug(task)}.png", lambda g=task_groups, t=task: curves_figure(t, g, n_boot, seed), task)

    # Stability.
    page.add(
        "## Stability",
        "",
        f"After a run first reaches {reach:g}, the share of its later evaluations below {below:g}, pooled over "
        f"the group's runs that reached {reach:g}; final and best are means over the group's runs of each run's "
        "last and best evaluation, selected the mean of the evaluations whose policy each run kept as "
        "`selected_policy.msgpack`, chosen by its learned reward alone (no true reward). Handed over below "
        f"{below:g}: the runs whose final, and whose selected, evaluation is below {below:g}.",
        "",
    )
    stability_body = []
    for key, members in groups.items():
        result = stability(members, reach, below)
        never = ", ".join(f"s{s}" for s in result.never_reached)
        last = sorted({int(run.steps[-1]) for run in members})
        reached_at = steps_text(last[0]) if len(last) == 1 else f"{steps_text(last[0])}-{steps_text(last[-1])}"
        stability_body.append(
            [
                key.env,
                key.method,
                key.variant,
                f"{result.runs} ({seed_kind(run.seed for run in members)})",
                f"{len(result.never_reached)}" + (f" ({never})" if never else ""),
                result.share_text,
                _num(result.final),
                result.selected_text,
                result.handed_over_text,
                _num(result.best),
                reached_at,
            ]
        )
    stability_header = [
        "task",
        "method",
        "variant",
        "runs",
        f"never reached {reach:g}",
        f"later evaluations below {below:g}",
        "final (mean)",
        "selected (mean)",
        f"handed over below {below:g} (final · selected)",
        "best (mean)",
        "last step",
    ]
    page.add(*_table(stability_header, stability_body), "")

    # Runs.
    page.add("## Runs", "", "Every run folder used, with the command that trained it (its `config.json`).", "")
    runs_body = [
        [
            f"`{run.folder}`",
            run.variant,
            run.env,
            run.method,
            f"{run.seed} ({seed_kind([run.seed])})",
            f"{steps_text(int(run.steps[-1]))} of {steps_text(run.planned_steps)}",
            f"`{run.command}`",
        ]
        for members in groups.values()
        for run in members
    ]
    page.add(*_table(["folder", "variant", "task", "method", "seed", "steps reached", "command"], runs_body))
    return "\n".join(page.lines) + "\n", page.figures


def write_report(
    runs: Sequence[Path],
    out: Path,
    at: Sequence[int] = (100_000, 300_000),
    n_boot: int = 2000,
    seed: int = 0,
    reach: float = 80.0,
    below: float = 50.0,
    claim_runs: Sequence[Path] = (),
) -> Path:
    """Write ``out/results.md`` and its figures ``out/img/*.png`` from the run folders ``runs``; returns the
    page's path.

    ``runs``: run folders, or folders holding them (see the module docstring); ``at``: the steps of the
    headline tables and aggregates; ``n_boot`` and ``seed``: the bootstrap's samples and seed; ``reach``
    and ``below``: the stability thresholds; ``claim_runs``: more run folders (or folders holding them) that
    only the claims table reads, such as ablation archives. Everything is read and drawn before anything is written;
    each file is replaced atomically, the page last, so a failure leaves no half-written page.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RankGameError(f"--out {out} is a file; give a folder for the page and its figures")
    if not at or any(step <= 0 for step in at):
        raise RankGameError(f"--at needs positive step counts (got {' '.join(map(str, at)) or 'none'})")
    if n_boot < 1:
        raise RankGameError(f"--boot must be positive (got {n_boot})")
    if not all(math.isfinite(value) for value in (reach, below)):
        raise RankGameError("the stability thresholds must be finite")
    at = list(dict.fromkeys(at))
    loaded = load_runs(runs)
    pyplot()  # a missing plot extra fails here, before any work
    text, figures = build_page(loaded, at, n_boot, seed, reach, below, load_runs(claim_runs))
    for name, data in figures.items():
        atomic_write_bytes(out / IMAGE_FOLDER / name, data)
    return atomic_write_bytes(out / PAGE_NAME, text.encode())
