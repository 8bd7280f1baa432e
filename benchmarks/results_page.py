"""Generate ``docs/results.md`` (and its figures in ``docs/img/``) from the archived runs, with one command.

    python benchmarks/results_page.py            # or: rankgame report ARCHIVES... --out docs

The archives named in :data:`ARCHIVES` are the runs the results page reports: the paper's settings on
the tuning seeds (0-2), the held-out seeds (100 and up), the baselines, and the recipes' variants. The
page labels each group with its archive folder, so what was tuned and what was held out stays visible.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from rankgame.report import write_report

REPO = Path(__file__).resolve().parents[1]
ROOT = Path("benchmarks") / "results"  # relative to REPO, so that the page names runs by repository paths

#: Archive folders of the results page, in the order they are read.
ARCHIVES = (
    "sample-efficiency",  # the paper's settings, seeds 0-2
    "stability-heldout-hopper-pal",  # the paper's settings, held-out seeds
    "selection-heldout-hopper-pal",  # the same, held-out seeds 105-109, with their selected policies
    "stability-heldout-hopper-pal-still",  # the same with standing still ranked (--rankings.still-weight 0.2)
    "stability-heldout-hopper-pal-tuned",  # --recipe tuned (k 1, r_max 1, patience 1), held-out seeds
    "stability-heldout-hopper-ral",  # RANK-RAL(auto), the paper's settings, held-out seeds
    "stability-heldout-walker-pal",  # RANK-PAL(auto) on Walker2d-v5, the paper's settings, held-out seeds
    "stability-heldout-walker-ral",  # RANK-RAL(auto) on Walker2d-v5, the same
    "stability-heldout-walker-pal-still",  # RANK-PAL(auto) on Walker2d-v5 with --rankings.still-weight 0.2
    "sample-efficiency-walker-pal-gp-10",  # Walker2d-v5 PAL, --reward.ranking-gradient-penalty 10, seeds 0-2
    "stability-heldout-walker-pal-gp-10",  # the same, held-out seeds
    "sample-efficiency-walker-pal-gp-1",  # the same with weight 1, seeds 0-2
    "modern-preset-tuning",  # RANK-PAL(auto) with --preset modern, tuning seeds
    "stability-sac-true-reward",  # SAC on the true reward (rankgame expert), the stability reference
    "sac-modern-true-reward",  # the same with --preset modern
    "baselines-lfo",  # GAIfO, DACfO, BCO, f-IRL, OPOLO (LfO, one expert trajectory)
    "lfd-hopper",  # RANK-PAL(auto) and RANK-RAL(auto) from demonstrations (LfD, one expert trajectory)
    "lfd-walker",  # RANK-PAL(auto) from demonstrations on Walker2d-v5
    "baselines-lfd",  # BC, DAC and IQ-Learn (LfD, one expert trajectory)
)

#: Archive folders that only the claims table reads (the ablations, the preference runs on Pen and Door and the
#: non-stationary runs).
CLAIM_ARCHIVES = (
    "ablations",
    "ablations-door",
    "ablations-door-100k",
    "trex-door",
    "trex-pen",
    "pen",
    "nonstationary",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=REPO / "docs")
    parser.add_argument("--boot", type=int, default=2000)
    args = parser.parse_args()
    out = args.out.resolve()
    os.chdir(REPO)
    archives = [ROOT / name for name in ARCHIVES if (ROOT / name).is_dir()]
    claim_archives = [ROOT / name for name in CLAIM_ARCHIVES if (ROOT / name).is_dir()]
    print(write_report(archives, out, n_boot=args.boot, claim_runs=claim_archives))


if __name__ == "__main__":
    main()
