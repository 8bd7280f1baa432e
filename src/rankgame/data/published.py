"""Published figures to compare runs with, each with its source.

* :data:`TABLE1`: the paper's asymptotic normalized scores of LfO methods at 2M environment steps
  (Sikchi et al. 2023, Table 1 and the appendix's extended table with Swimmer, IMIT-PAL and IMIT-RAL):
  mean and standard deviation over 5 seeds, each seed the mean of 10 evaluation episodes; one expert
  trajectory of observations. The paper's tasks are gym -v2; rankgame's names map them to Gymnasium v5.
* :data:`RELEASED_CURVES`: the authors' released learning curves of RANK-PAL(auto) and RANK-RAL(auto)
  (hari-sikchi/rank-game, ``learning_curves/LfO/*/{pal,ral}_results.txt``), mean return over their seeds
  normalized by their experts and random returns (Hopper 3536 / 13.8, HalfCheetah 13051 / -271.9,
  Walker2d 5457 / 1.5, Ant 5926 / -62.0, Humanoid 5566 / 112.2), read at 100k and 300k steps. Each
  released curve is a moving average over 20 evaluations, one every 1000 steps.
"""

from __future__ import annotations

#: (mean, standard deviation) of the normalized score at 2M steps, by method and task (the paper, Table 1).
TABLE1: dict[str, dict[str, tuple[float, float]]] = {
    "bco": {
        "Swimmer-v5": (102.76, 0.90),
        "Hopper-v5": (20.10, 2.15),
        "HalfCheetah-v5": (5.12, 3.82),
        "Walker2d-v5": (4.00, 1.25),
        "Ant-v5": (12.80, 1.26),
        "Humanoid-v5": (3.90, 1.24),
    },
    "gaifo": {
        "Swimmer-v5": (99.04, 1.61),
        "Hopper-v5": (81.13, 9.99),
        "HalfCheetah-v5": (13.54, 7.24),
        "Walker2d-v5": (83.83, 2.55),
        "Ant-v5": (20.10, 24.41),
        "Humanoid-v5": (3.93, 1.81),
    },
    "dacfo": {
        "Swimmer-v5": (95.09, 6.14),
        "Hopper-v5": (94.73, 3.63),
        "HalfCheetah-v5": (85.03, 5.09),
        "Walker2d-v5": (54.70, 44.64),
        "Ant-v5": (86.45, 1.67),
        "Humanoid-v5": (19.31, 32.19),
    },
    "f-irl": {
        "Swimmer-v5": (103.89, 2.37),
        "Hopper-v5": (97.45, 0.61),
        "HalfCheetah-v5": (96.06, 4.63),
        "Walker2d-v5": (101.16, 1.25),
        "Ant-v5": (71.18, 19.80),
        "Humanoid-v5": (77.93, 6.372),
    },
    "opolo": {
        "Swimmer-v5": (98.64, 0.14),
        "Hopper-v5": (89.56, 5.46),
        "HalfCheetah-v5": (88.92, 3.20),
        "Walker2d-v5": (79.19, 24.35),
        "Ant-v5": (93.37, 3.78),
        "Humanoid-v5": (24.87, 17.04),
    },
    "imit-pal": {
        "Swimmer-v5": (105.93, 3.12),
        "Hopper-v5": (86.47, 7.66),
        "HalfCheetah-v5": (90.65, 15.17),
        "Walker2d-v5": (75.60, 1.90),
        "Ant-v5": (82.40, 9.05),
        "Humanoid-v5": (94.49, 3.21),
    },
    "imit-ral": {
        "Swimmer-v5": (100.35, 3.6),
        "Hopper-v5": (92.34, 8.63),
        "HalfCheetah-v5": (96.80, 2.45),
        "Walker2d-v5": (94.41, 2.94),
        "Ant-v5": (78.06, 4.24),
        "Humanoid-v5": (91.27, 9.33),
    },
    "rank-pal-auto": {
        "Swimmer-v5": (98.83, 0.09),
        "Hopper-v5": (87.14, 16.14),
        "HalfCheetah-v5": (94.05, 3.59),
        "Walker2d-v5": (93.88, 0.72),
        "Ant-v5": (98.93, 1.83),
        "Humanoid-v5": (96.84, 3.28),
    },
    "rank-ral-auto": {
        "Swimmer-v5": (99.31, 1.50),
        "Hopper-v5": (99.34, 0.20),
        "HalfCheetah-v5": (101.14, 7.45),
        "Walker2d-v5": (93.24, 1.25),
        "Ant-v5": (93.21, 2.98),
        "Humanoid-v5": (94.45, 4.13),
    },
}

#: Normalized score of the authors' released curves at 100k and 300k steps, by method and task.
RELEASED_CURVES: dict[str, dict[str, dict[int, float]]] = {
    "rank-pal-auto": {
        "Hopper-v5": {100_000: 86, 300_000: 92},
        "HalfCheetah-v5": {100_000: 47, 300_000: 79},
        "Walker2d-v5": {100_000: 18, 300_000: 65},
        "Ant-v5": {100_000: 22, 300_000: 80},
        "Humanoid-v5": {100_000: 5, 300_000: 68},
    },
    "rank-ral-auto": {
        "Hopper-v5": {100_000: 92, 300_000: 97},
        "HalfCheetah-v5": {100_000: 20, 300_000: 72},
        "Walker2d-v5": {100_000: 22, 300_000: 87},
        "Ant-v5": {100_000: 39, 300_000: 69},
        "Humanoid-v5": {100_000: 4, 300_000: 49},
    },
}
