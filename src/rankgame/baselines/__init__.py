"""Imitation baselines outside the ranking game, as trainers of the run harness (:mod:`rankgame.run`).

* :mod:`rankgame.baselines.cloning`: behavior cloning (BC, learning from demonstration: the expert's
  states and actions; Pomerleau, 1991; Bain & Sammut, 1995), and what every cloned policy shares;
* :mod:`rankgame.baselines.inverse_dynamics`: an inverse dynamics model ``a = g(s, s')``;
* :mod:`rankgame.baselines.bco`: behavioral cloning from observation, BCO(alpha) (learning from
  observation: the expert's states only; Torabi, Warnell & Stone, 2018).
"""
