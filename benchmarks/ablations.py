"""The paper's ablations (App. D) as named sets of ``rankgame train`` variants, run and summarized together.

Each ablation compares a few variants of RANK-PAL / RANK-RAL on the same tasks and seeds; a variant is a
method and the options that differ from the paper's defaults. Runs go to ``--root/ABLATION/VARIANT``
and, once finished, their ``metrics.csv`` and ``config.json`` are archived under
``--archive/ABLATION/VARIANT`` (runs already archived are not repeated), exactly as in
``sample_efficiency.py``, whose runner (a local ``rankgame sweep``) this uses. The summary is the mean
and standard deviation over seeds of the normalized score at each ``--at`` step, as JSON and as a
Markdown table, followed by a table of every run: the first evaluation at ``--threshold`` and the
median, minimum and maximum of the evaluations in the second half of the run.

    python benchmarks/ablations.py --list
    python benchmarks/ablations.py reward-range --envs Hopper-v5 --steps 100000 --at 50000 100000 --dry-run
    python benchmarks/ablations.py rankings --envs Hopper-v5 --seeds 0 1 2 --steps 100000 --cores 2
    python benchmarks/ablations.py rankings --envs Hopper-v5 --steps 100000 --summarize-only --plot rankings.png

On Pen and Door, ``--metric success`` summarizes the success rate (percent of evaluation episodes)
instead of the normalized score, and ``--plot`` then draws the success rate (share of episodes);
``--train-args`` adds options to every variant:

    python benchmarks/ablations.py preference-noise --envs rankgame/Door-v0 --seeds 0 --steps 100000 \\
        --at 50000 100000 --train-args "--preset modern" --metric success --threshold 80
"""

from __future__ import annotations

import argparse
import json
import shlex
from dataclasses import dataclass
from pathlib import Path

from sample_efficiency import (
    METRICS,
    TRAIN_ARGS_NOTE,
    Job,
    curve_mean,
    env_folder_name,
    first_step_text,
    logged_folder,
    mean_and_std,
    read_scores,
    run_jobs,
    run_profile,
    spread_text,
)


@dataclass(frozen=True)
class Variant:
    """One arm of an ablation: a label, a method and its options beyond the defaults."""

    label: str
    method: str
    train_args: str = ""


@dataclass(frozen=True)
class Ablation:
    """What the paper asks (and where), and the variants that answer it; the first is the reference."""

    section: str
    question: str
    variants: tuple[Variant, ...]


ABLATIONS: dict[str, Ablation] = {
    "rankings": Ablation(
        "App. D, utility of automatically generated rankings",
        "how much do the automatically generated rankings help?",
        (Variant("auto", "rank-pal-auto"), Variant("vanilla", "rank-pal-vanilla")),
    ),
    "loss": Ablation(
        "App. D, comparison of imit-game and rank-game",
        "the regression ranking loss L_k against the supremum loss of adversarial imitation (IMIT)",
        (
            Variant("rank-pal", "rank-pal-auto"),
            Variant("imit-pal", "imit-pal"),
            Variant("rank-ral", "rank-ral-auto"),
            Variant("imit-ral", "imit-ral"),
        ),
    ),
    "shaping": Ablation(
        "App. D, parameterized reward shaping",
        "how the targets of the auto mixtures are shaped: linear, or exp with temperature beta",
        (
            Variant("exp-beta-m1", "rank-pal-auto"),
            Variant("linear", "rank-pal-auto", "--rankings.schedule linear"),
            Variant("exp-beta-1", "rank-pal-auto", "--rankings.beta 1"),
            Variant("exp-beta-m2", "rank-pal-auto", "--rankings.beta -2"),
            Variant("exp-beta-m5", "rank-pal-auto", "--rankings.beta -5"),
        ),
    ),
    "policy-updates": Ablation(
        "App. D, Stackelberg game design",
        "Stackelberg design: policy updates (and environment steps) per game iteration, n_pol, for PAL",
        (
            Variant("n-pol-1000", "rank-pal-auto"),
            Variant("n-pol-500", "rank-pal-auto", "--policy-updates 500"),
            Variant("n-pol-2000", "rank-pal-auto", "--policy-updates 2000"),
            Variant("n-pol-5000", "rank-pal-auto", "--policy-updates 5000"),
        ),
    ),
    "reward-budget": Ablation(
        "App. D, Stackelberg game design",
        "Stackelberg design: how long the reward trains per iteration, until its holdout stops improving"
        " or n_rew = passes |D| / batch steps, for each leader; -all-rows: budgets count the absorbing padding",
        (
            Variant("pal-holdout", "rank-pal-auto"),
            Variant("pal-holdout-all-rows", "rank-pal-auto", "--ablation.budget-rows all"),
            Variant("pal-passes-6", "rank-pal-auto", "--ablation.budget passes --leader.ral-passes 6"),
            Variant("pal-passes-30", "rank-pal-auto", "--ablation.budget passes --leader.ral-passes 30"),
            Variant("ral-passes-1", "rank-ral-auto"),
            Variant("ral-passes-6", "rank-ral-auto", "--leader.ral-passes 6"),
            Variant("ral-holdout", "rank-ral-auto", "--ablation.budget holdout"),
            Variant("ral-passes-1-all-rows", "rank-ral-auto", "--ablation.budget-rows all"),
        ),
    ),
    "reward-range": Ablation(
        "App. D, sensitivity of the reward range",
        "the performance gap k, with the reward bounded to [-k, k] (R_max = k)",
        (
            Variant("k-10", "rank-pal-auto"),
            Variant("k-1", "rank-pal-auto", "--rankings.k 1 --reward.r-max 1"),
            Variant("k-5", "rank-pal-auto", "--rankings.k 5 --reward.r-max 5"),
            Variant("k-20", "rank-pal-auto", "--rankings.k 20 --reward.r-max 20"),
            Variant("k-50", "rank-pal-auto", "--rankings.k 50 --reward.r-max 50"),
        ),
    ),
    "regularizer": Ablation(
        "App. D, effect of the regularizer",
        "auto rankings (trajectory mixup) as a regularizer, against weight decay, spectral normalization"
        " and state mixup",
        (
            Variant("auto", "rank-pal-auto"),
            Variant("vanilla-wd-1e-4", "rank-pal-vanilla"),
            Variant("vanilla-wd-1e-2", "rank-pal-vanilla", "--reward.weight-decay 1e-2"),
            Variant("vanilla-sn", "rank-pal-vanilla", "--ablation.spectral-norm"),
            Variant("state-mixup", "rank-pal-auto", "--ablation.mixup state"),
        ),
    ),
    "expert-trajectories": Ablation(
        "App. D, varying number of expert trajectories",
        "the number of expert trajectories",
        (
            Variant("1", "rank-pal-auto"),
            Variant("5", "rank-pal-auto", "--expert-trajectories 5"),
            Variant("10", "rank-pal-auto", "--expert-trajectories 10"),
        ),
    ),
    "preferences": Ablation(
        "Sec. 5, utility of preferences",
        "offline rankings (pref) against auto rankings, on tasks with shipped preference data",
        (
            Variant("pal-auto", "rank-pal-auto"),
            Variant("pal-pref", "rank-pal-pref"),
            Variant("ral-auto", "rank-ral-auto"),
            Variant("ral-pref", "rank-ral-pref"),
        ),
    ),
    "preference-noise": Ablation(
        "App. D, robustness to noisy preferences",
        "a share of the offline labels replaced by another trajectory's rank (the paper uses Door)",
        (
            Variant("noise-0", "rank-pal-pref"),
            Variant("noise-0.2", "rank-pal-pref", "--rankings.pref-noise 0.2"),
            Variant("noise-0.4", "rank-pal-pref", "--rankings.pref-noise 0.4"),
            Variant("noise-0.6", "rank-pal-pref", "--rankings.pref-noise 0.6"),
        ),
    ),
}


def ablation_jobs(
    name: str,
    envs: list[str],
    seeds: list[int],
    root: Path,
    archive: Path,
    labels: list[str] | None = None,
    common_args: str = "",
) -> list[tuple[Variant, Job]]:
    """Every (variant, env, seed) run of an ablation, variant by variant (only the variants named in
    ``labels`` if given; an unknown label raises ``ValueError``); ``common_args`` are options of every
    run, placed before the variant's own."""
    variants = ABLATIONS[name].variants
    if labels is not None:
        unknown = sorted(set(labels) - {variant.label for variant in variants})
        if unknown:
            raise ValueError(f"{name} has no variant {', '.join(unknown)} (see --list)")
        variants = tuple(variant for variant in variants if variant.label in labels)
    return [
        (
            variant,
            Job(
                root / name / variant.label / f"{env_folder_name(env)}__s{seed}",
                archive / name / variant.label / f"{env_folder_name(env)}__s{seed}",
                env,
                variant.method,
                seed,
                f"{common_args} {variant.train_args}".strip(),
            ),
        )
        for variant in variants
        for env in envs
        for seed in seeds
    ]


def summarize(
    jobs: list[tuple[Variant, Job]], at: list[int], steps: int, threshold: float = 80.0, metric: str = "normalized"
) -> list[dict]:
    """One row per (env, variant): over seeds, the mean and standard deviation of the score (``metric``
    of :func:`read_scores`) at each step of ``at`` and of each run's mean over all its evaluations up to
    ``steps`` (the area under its learning curve, steadier than any single evaluation; only runs that
    reached ``steps``), and under ``runs`` the :func:`run_profile` of each run that reached ``steps``,
    with its seed."""
    groups: dict[tuple[str, str], list[tuple[int, dict[int, float]]]] = {}
    for variant, job in jobs:
        groups.setdefault((job.env, variant.label), []).append((job.seed, read_scores(job.out, job.archived, metric)))
    rows = []
    for (env, label), seeded_runs in groups.items():
        runs = [run for _, run in seeded_runs]
        row: dict = {"env": env, "variant": label, "at": []}
        for step in at:
            scores = [run[step] for run in runs if step in run]
            mean, std = mean_and_std(scores)
            row["at"].append({"step": step, "seeds": len(scores), "mean": mean, "std": std})
        finished = [run for run in runs if steps in run]
        row["curve_mean"], row["curve_std"] = mean_and_std([curve_mean(run, steps) for run in finished])
        row["curve_seeds"] = len(finished)
        profiles = [(seed, run_profile(run, steps, threshold)) for seed, run in seeded_runs]
        row["runs"] = [{"seed": seed, **profile} for seed, profile in profiles if profile is not None]
        rows.append(row)
    return rows


def markdown_table(rows: list[dict], at: list[int], steps: int) -> str:
    """The summary as a Markdown table: one row per (env, variant), one column per step of ``at``."""

    def cell(mean: float | None, std: float | None, seeds: int) -> str:
        if mean is None:
            return "-"
        return f"{mean} ({seeds})" if std is None else f"{mean} ± {std} ({seeds})"

    header = " | ".join(f"{step // 1000}k" for step in at)
    lines = [
        f"| env | variant | {header} | mean of the evaluations to {steps // 1000}k |",
        "| --- | --- | " + "--- | " * len(at) + "--- |",
    ]
    for row in rows:
        points = " | ".join(cell(point["mean"], point["std"], point["seeds"]) for point in row["at"])
        curve = cell(row["curve_mean"], row["curve_std"], row["curve_seeds"])
        lines.append(f"| {row['env']} | {row['variant']} | {points} | {curve} |")
    return "\n".join(lines)


def per_seed_table(rows: list[dict], steps: int, threshold: float = 80.0) -> str:
    """The runs of each (env, variant) of :func:`summarize` as a Markdown table: per seed, in seed order,
    the first step at ``threshold`` and the median / minimum / maximum over the second half of the run."""
    lines = [
        f"| env | variant | first step at >= {threshold:g}, per seed "
        f"| median / min / max over {steps // 2000}k-{steps // 1000}k, per seed |",
        "| --- | --- | --- | --- |",
    ]
    for row in rows:
        firsts = ", ".join(first_step_text(run) for run in row["runs"])
        spreads = ", ".join(spread_text(run) for run in row["runs"])
        lines.append(f"| {row['env']} | {row['variant']} | {firsts or '-'} | {spreads or '-'} |")
    return "\n".join(lines)


def plot_ablation(
    name: str, jobs: list[tuple[Variant, Job]], steps: int, out: Path, metric: str = "normalized"
) -> list[Path]:
    """Draw, per env, one curve per variant (mean over its seeds, band of one standard deviation) of the
    ``metric``'s column up to ``steps`` into ``out`` (``out`` with ``-ENV`` before its suffix when there
    are several envs). Each run is read from its folder, else from its archive, like the summary."""
    from rankgame.plot import plot_groups

    envs = list(dict.fromkeys(job.env for _, job in jobs))
    figures = []
    for env in envs:
        groups: dict[str, list[Path]] = {}
        for variant, job in jobs:
            folder = logged_folder(job.out, job.archived)
            if job.env == env and folder is not None:
                groups.setdefault(variant.label, []).append(folder)
        if not groups:
            continue
        figure = out if len(envs) == 1 else out.with_name(f"{out.stem}-{env_folder_name(env)}{out.suffix}")
        title = f"{env}: {name} ({ABLATIONS[name].section})"
        column = METRICS[metric].column
        figures.append(plot_groups(list(groups.items()), figure, column, title=title, max_steps=steps))
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("ablation", nargs="?", choices=list(ABLATIONS), help="which ablation to run or summarize")
    parser.add_argument("--list", action="store_true", help="list the ablations and their variants")
    parser.add_argument("--envs", nargs="+", default=["Hopper-v5"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--variants", nargs="+", metavar="LABEL", help="only these variants (default: all)")
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--at", nargs="+", type=int, default=[100_000, 300_000])
    parser.add_argument("--threshold", type=float, default=80.0, help="score whose first crossing is reported")
    parser.add_argument(
        "--metric",
        choices=list(METRICS),
        default="normalized",
        help="what to summarize: the normalized score, or the success rate in percent (Pen, Door)",
    )
    parser.add_argument(
        "--train-args",
        default="",
        help=f"options for every run, before the variant's own, e.g. '--preset modern'; {TRAIN_ARGS_NOTE}",
    )
    parser.add_argument("--root", type=Path, default=Path("runs/ablations"))
    parser.add_argument("--archive", type=Path, default=Path("benchmarks/results/ablations"))
    parser.add_argument("--cores", type=int, help="runs at once (default: the machine's cores)")
    parser.add_argument("--dry-run", action="store_true", help="print the training commands without running them")
    parser.add_argument("--summarize-only", action="store_true")
    parser.add_argument("--plot", type=Path, metavar="FILE", help="also draw the curves (plot extra)")
    args = parser.parse_args()
    if args.list:
        for name, ablation in ABLATIONS.items():
            print(f"{name} ({ablation.section}): {ablation.question}")
            for variant in ablation.variants:
                print(f"    {variant.label:<16} {variant.method:<17} {variant.train_args}")
        return
    if args.ablation is None:
        parser.error("name an ablation (see --list)")
    try:
        jobs = ablation_jobs(
            args.ablation, args.envs, args.seeds, args.root, args.archive, args.variants, args.train_args
        )
    except ValueError as exc:
        parser.error(str(exc))
    if args.dry_run:
        for _, job in jobs:
            line = shlex.join(job.command(args.steps))
            print(f"# archived, not run: {line}" if (job.archived / "metrics.csv").exists() else line)
        return
    if not args.summarize_only:
        run_jobs([job for _, job in jobs], args.steps, args.root, args.cores)
    rows = summarize(jobs, args.at, args.steps, args.threshold, args.metric)
    print(json.dumps({"ablation": args.ablation, "steps": args.steps, "metric": args.metric, "variants": rows}))
    print(f"\n{METRICS[args.metric].label}, mean ± standard deviation (seeds)\n")
    print(markdown_table(rows, args.at, args.steps))
    print()
    print(per_seed_table(rows, args.steps, args.threshold))
    if args.plot is not None:
        for figure in plot_ablation(args.ablation, jobs, args.steps, args.plot, args.metric):
            print(f"wrote {figure}")


if __name__ == "__main__":
    main()
