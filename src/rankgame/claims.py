"""The paper's claims as comparisons between groups of runs, each with a verdict computed from the data.

A :class:`Claim` is a statement of the paper, the paper's own figure for it, and the comparisons that
test it: "group A scores higher than group B on task T at step S" (``higher``, on the normalized score
or, on Pen and Door, the success rate) or "group A collapses less often than group B" (``steadier``:
the share of evaluations below 50 after a run first reaches 80, :func:`rankgame.report.stability`).
A group is a method and the variant (archive or sweep folder) its runs are in; a variant of None means
the method's largest group on that task, whatever its folder.

:func:`judge` gives a claim its verdict: ``reproduced`` when every comparison that has runs on both
sides holds, ``not reproduced`` when one of them does not, ``not run`` when none has runs on both sides.
Means over few seeds decide, so every measured figure shows the sample standard deviation and the
number of runs beside its mean: a verdict whose gap is smaller than the spread is not a significant
margin. :data:`CLAIMS` refers to the archive folders of ``benchmarks/results`` (the results page's);
with other runs most claims read ``not run``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

from rankgame.stats import mean_and_sample_std

Metric = Literal["score", "success"]
Verdict = Literal["reproduced", "not reproduced", "not run"]
LOCOMOTION = ("Hopper-v5", "HalfCheetah-v5", "Walker2d-v5", "Ant-v5")


@dataclass(frozen=True)
class Side:
    """One side of a comparison: a method and the variant its runs are in (None: its largest group)."""

    method: str
    variant: str | None = None
    label: str = ""
    """How the measured figure names it (default: the method)."""

    @property
    def name(self) -> str:
        return self.label or self.method


@dataclass(frozen=True)
class Comparison:
    """``better`` beats ``worse`` on ``env``: a higher mean ``metric`` at ``step`` (``higher``) or a smaller
    share of collapsed evaluations (``steadier``, ``step`` unused)."""

    better: Side
    worse: Side
    env: str
    step: int = 100_000
    metric: Metric = "score"


@dataclass(frozen=True)
class Claim:
    """A statement of the paper, where it is made, the paper's figure for it, and its comparisons."""

    statement: str
    source: str
    paper: str
    comparisons: tuple[Comparison, ...]
    kind: Literal["higher", "steadier"] = "higher"


#: ``(side, env, step, metric) -> the runs' values at that step``, empty if no run has one.
ValuesAt = Callable[[Side, str, int, Metric], Sequence[float]]
#: ``(side, env) -> (collapsed, evaluations after first reaching 80)`` (``(0, 0)`` if no run reached 80),
#: None without runs.
Collapses = Callable[[Side, str], tuple[int, int] | None]


def _steps(step: int) -> str:
    return f"{step // 1000}k" if step % 1000 == 0 else str(step)


def _measure(values: Sequence[float], metric: Metric) -> str:
    """The mean of ``values`` and, from two runs on, their sample standard deviation (n - 1), with n."""
    scale, unit, digits = (100.0, "%", 0) if metric == "success" else (1.0, "", 1)
    mean, std = mean_and_sample_std(values)
    text = f"{scale * mean:.{digits}f}{unit}"
    if std is not None:
        text += f" ± {scale * std:.{digits}f}{unit}"
    return f"{text} (n={len(values)})"


def judge(claim: Claim, values_at: ValuesAt, collapses: Collapses) -> tuple[str, Verdict]:
    """The measured figures of ``claim``'s comparisons (``; ``-separated, ``n`` runs each) and its verdict
    (see the module docstring)."""
    parts, held = [], []
    for c in claim.comparisons:
        where = c.env if claim.kind == "steadier" else f"{c.env} at {_steps(c.step)}"
        if claim.kind == "steadier":
            a, b = collapses(c.better, c.env), collapses(c.worse, c.env)
            if a is None or b is None:
                parts.append(f"{c.better.name} vs {c.worse.name}, {where}: not run")
                continue
            if not a[1] or not b[1]:
                never = ", ".join(side.name for side, n in ((c.better, a), (c.worse, b)) if not n[1])
                parts.append(f"{c.better.name} vs {c.worse.name}, {where}: {never} never reached 80")
                continue
            share_a, share_b = a[0] / a[1], b[0] / b[1]
            held.append(share_a < share_b)
            text = f"{a[0]}/{a[1]} = {100 * share_a:.0f}% vs {b[0]}/{b[1]} = {100 * share_b:.0f}%"
            parts.append(f"{c.better.name} vs {c.worse.name}, {where}: {text}")
            continue
        x, y = values_at(c.better, c.env, c.step, c.metric), values_at(c.worse, c.env, c.step, c.metric)
        if not x or not y:
            parts.append(f"{c.better.name} vs {c.worse.name}, {where}: not run")
            continue
        held.append(sum(x) / len(x) > sum(y) / len(y))
        text = f"{_measure(x, c.metric)} vs {_measure(y, c.metric)}"
        parts.append(f"{c.better.name} vs {c.worse.name}, {where}: {text}")
    verdict: Verdict = "not run" if not held else "reproduced" if all(held) else "not reproduced"
    return "; ".join(parts), verdict


def _beats_baseline(baseline: str, name: str, paper: str) -> Claim:
    ours = Side("rank-pal-auto", "sample-efficiency", "RANK-PAL(auto)")
    return Claim(
        f"RANK-PAL(auto) is more sample-efficient than {name} (LfO, one expert trajectory)",
        "Sec. 5.1, Fig. 2",
        paper,
        tuple(Comparison(ours, Side(baseline, label=name), env) for env in LOCOMOTION),
    )


def _ablation(name: str, better: str, method: str, worse: Sequence[tuple[str, str]]) -> tuple[Comparison, ...]:
    """Comparisons on Hopper-v5 at 100k between variants of the ablation ``name`` (``benchmarks/ablations.py``)."""
    side = Side(method, f"ablations/{name}/{better}", better)
    return tuple(Comparison(side, Side(m, f"ablations/{name}/{label}", label), "Hopper-v5") for label, m in worse)


_DOOR = "ablations-door/preferences"
_NOISE = "ablations-door/preference-noise"
_DOOR_100K = "ablations-door-100k/preferences"

#: The paper's claims the results page checks.
CLAIMS: tuple[Claim, ...] = (
    _beats_baseline("opolo", "OPOLO", "higher curve throughout; 'outperforming OPOLO by a significant margin'"),
    _beats_baseline("f-irl", "f-IRL", "higher curve early on; f-IRL ahead on Walker at 2M (101.2 vs 93.9)"),
    _beats_baseline("dacfo", "DACfO", "higher curve throughout"),
    _beats_baseline("gaifo", "GAIfO", "higher curve throughout"),
    _beats_baseline("bco", "BCO", "higher curve throughout"),
    Claim(
        "rank-game is more stable than adversarial imitation",
        "Sec. 1, Sec. 5.1",
        "stated, not measured",
        tuple(
            Comparison(Side("rank-pal-auto", "sample-efficiency", "RANK-PAL(auto)"), Side(m, label=name), env)
            for m, name in (("dacfo", "DACfO"), ("gaifo", "GAIfO"))
            for env in ("Hopper-v5", "Walker2d-v5")
        ),
        kind="steadier",
    ),
    Claim(
        "offline preferences solve Pen and Door, which RANK-PAL(auto) from observations alone does not",
        "Sec. 5.2, Fig. 4",
        "RANK-PAL(pref) and RANK-RAL(pref) near-expert success; the LfO methods near 0",
        (
            Comparison(
                Side("rank-pal-pref", _DOOR + "/pal-pref", "RANK-PAL(pref)"),
                Side("rank-pal-auto", _DOOR + "/pal-auto", "RANK-PAL(auto)"),
                "rankgame/Door-v0",
                step=60_000,
                metric="success",
            ),
            Comparison(
                Side("rank-ral-pref", _DOOR_100K + "/ral-pref", "RANK-RAL(pref)"),
                Side("rank-pal-auto", _DOOR_100K + "/pal-auto", "RANK-PAL(auto)"),
                "rankgame/Door-v0",
                metric="success",
            ),
        )
        + tuple(
            # Pen: the Pen expert's SAC settings, the shipped 10 preferences, at 500k
            Comparison(
                Side(method, "trex-pen/p10", label),
                Side("rank-pal-auto", "pen/expert-sac", "RANK-PAL(auto)"),
                "rankgame/Pen-v0",
                step=500_000,
                metric="success",
            )
            for method, label in (("rank-pal-pref", "RANK-PAL(pref)"), ("rank-ral-pref", "RANK-RAL(pref)"))
        ),
    ),
    Claim(
        "RANK-PAL(pref) solves Pen and Door from preferences that T-REX, given 10, 20 or 50 of them, does not solve",
        "Sec. 5.2, App. 'Learning purely from offline rankings'",
        "T-REX with 10, 20 or 50 preferences sampled from a SAC replay buffer does not solve Pen or Door",
        tuple(
            Comparison(
                Side("rank-pal-pref", variant, f"RANK-PAL(pref) ({count} preferences)"),
                Side("trex", f"trex-door/p{count}", f"T-REX ({count} preferences)"),
                "rankgame/Door-v0",
                metric="success",
            )
            # both sides read the same preferences: the shipped 10, or the 20 and 50 drawn for T-REX
            for count, variant in ((10, _DOOR_100K + "/pal-pref"), (20, "trex-door/p20"), (50, "trex-door/p50"))
        )
        + tuple(
            # Pen: the Pen expert's SAC settings, 500k steps; the shipped 10 preferences, or 20 and 50
            # drawn from a rerun of the Pen expert's training
            Comparison(
                Side("rank-pal-pref", f"trex-pen/p{count}", f"RANK-PAL(pref) ({count} preferences)"),
                Side("trex", f"trex-pen/p{count}", f"T-REX ({count} preferences)"),
                "rankgame/Pen-v0",
                step=500_000,
                metric="success",
            )
            for count in (10, 20, 50)
        ),
    ),
    Claim(
        "from demonstrations, RANK-PAL(auto) scores higher at 100k than DAC and IQ-Learn",
        "App. 'Evaluation of LfD'",
        "rank-game among the most sample-efficient LfD methods, competitive with IQ-Learn, DAC and BC (figure only)",
        tuple(
            Comparison(Side("rank-pal-auto", archive, "RANK-PAL(auto) LfD"), Side(m, "baselines-lfd", name), env)
            for m, name in (("dac", "DAC"), ("iq-learn", "IQ-Learn"))
            for env, archive in (("Hopper-v5", "lfd-hopper"), ("Walker2d-v5", "lfd-walker"))
        ),
    ),
    Claim(
        "RANK-PAL adapts faster than RANK-RAL when the expert's intent changes (switch at 100k)",
        "Sec. 5.3, Fig. 5",
        "PAL recovers sooner after the switch",
        (
            Comparison(
                Side("rank-pal-auto", "nonstationary/backward", "PAL"),
                Side("rank-ral-auto", "nonstationary/backward", "RAL"),
                "Hopper-v5",
                step=150_000,
            ),
        ),
    ),
    Claim(
        "RANK-RAL adapts faster than RANK-PAL when the dynamics change (switch at 100k)",
        "Sec. 5.3, Fig. 5",
        "RAL recovers sooner after the switch",
        (
            Comparison(
                Side("rank-ral-auto", "nonstationary/heavy", "RAL"),
                Side("rank-pal-auto", "nonstationary/heavy", "PAL"),
                "Hopper-v5",
                step=150_000,
            ),
        ),
    ),
    Claim(
        "automatically generated rankings beat the vanilla agent-below-expert ranking",
        "Sec. 5.4, Fig. 6",
        "auto ahead of vanilla",
        _ablation("rankings", "auto", "rank-pal-auto", [("vanilla", "rank-pal-vanilla")]),
    ),
    Claim(
        "the ranking loss L_k beats the supremum loss of adversarial imitation (IMIT)",
        "App. D.3",
        "RANK ahead of IMIT for PAL and RAL",
        (
            *_ablation("loss", "rank-pal", "rank-pal-auto", [("imit-pal", "imit-pal")]),
            *_ablation("loss", "rank-ral", "rank-ral-auto", [("imit-ral", "imit-ral")]),
        ),
    ),
    Claim(
        "an intermediate reward range works best, k = 10",
        "App. D, reward range",
        "k = 10 best of 1, 5, 10, 20, 50",
        _ablation("reward-range", "k-10", "rank-pal-auto", [(f"k-{k}", "rank-pal-auto") for k in (1, 5, 20, 50)]),
    ),
    Claim(
        "exponential shaping with temperature -1 beats linear targets and other temperatures",
        "App. D, shaping",
        "exp(-1) most sample-efficient; too negative a temperature falls",
        _ablation(
            "shaping",
            "exp-beta-m1",
            "rank-pal-auto",
            [(label, "rank-pal-auto") for label in ("linear", "exp-beta-1", "exp-beta-m2", "exp-beta-m5")],
        ),
    ),
    Claim(
        "more expert trajectories help",
        "App. D, expert trajectories",
        "faster learning with more trajectories",
        _ablation("expert-trajectories", "10", "rank-pal-auto", [("1", "rank-pal-auto")])
        + _ablation("expert-trajectories", "5", "rank-pal-auto", [("1", "rank-pal-auto")]),
    ),
    Claim(
        "RANK-PAL(pref) is robust to noisy preferences: with 20% or 40% of them flipped it still beats no preferences",
        "App. D, Fig. 'noisy preferences'",
        "'considerable robustness to noisy preferences'",
        tuple(
            Comparison(
                Side("rank-pal-pref", f"{_NOISE}/noise-{noise}", f"noise {noise}"),
                Side("rank-pal-auto", _DOOR + "/pal-auto", "no preferences"),
                "rankgame/Door-v0",
                step=60_000,
                metric="success",
            )
            for noise in ("0.2", "0.4")
        ),
    ),
)
