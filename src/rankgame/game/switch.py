"""Non-stationary imitation (Sec. 5.3): the task and/or the expert change after ``--switch.at`` steps.

From the switch on, the policy acts in and is evaluated on ``--switch.env`` (same spaces and horizon),
and the agent is ranked below ``--switch.expert`` (default: the shipped expert of ``--switch.env`` if
there is one, else the same expert as before; scores are normalized by the expert being imitated).
The pref methods' offline rankings lie below the first expert, so with them only the task may change.
The replay buffer, the ranking data and both players' parameters carry over; the episode in progress
is abandoned. Evaluations at steps up to ``--switch.at`` are on the first task.
"""

from __future__ import annotations

from dataclasses import dataclass

from rankgame.config import TrainConfig
from rankgame.data.experts import shipped_envs
from rankgame.data.trajectories import TrajectoryFile
from rankgame.envs.make import EnvSpec, env_spec, make_env
from rankgame.errors import RankGameError
from rankgame.game.data import DataSource, resolve_expert
from rankgame.game.methods import METHODS


@dataclass(frozen=True)
class TaskSwitch:
    """The change at step ``at``: the new task (None: the same) and the new expert (None: the same)."""

    at: int
    env_id: str | None
    expert: TrajectoryFile | None

    def due(self, step: int) -> bool:
        """Whether environment step ``step`` is the first one after the switch."""
        return step == self.at + 1


def plan_switch(cfg: TrainConfig, spec: EnvSpec, expert: DataSource = None) -> TaskSwitch | None:
    """Check ``--switch.env`` and the switch expert (``expert``, else ``--switch.expert``) before training
    starts; None when the run has no switch."""
    switch = cfg.switch
    if switch.at is None:
        return None
    if switch.env is not None:
        env = make_env(switch.env)
        new = env_spec(env)
        env.close()
        shapes = [(s.obs_dim, s.act_dim, s.max_episode_steps) for s in (new, spec)]
        if shapes[0] != shapes[1]:
            raise RankGameError(
                f"--switch.env {switch.env} has (obs_dim, act_dim, horizon) = {shapes[0]}; {cfg.env} has {shapes[1]}"
            )
    source = expert if expert is not None else switch.expert
    if source is not None and METHODS[cfg.method].uses_preferences:
        raise RankGameError("a switch expert cannot be combined with the pref methods' offline rankings")
    if source is None and switch.env not in shipped_envs():
        return TaskSwitch(switch.at, switch.env, None)
    data = resolve_expert(source, switch.env or cfg.env, spec, cfg.expert_trajectories, "--switch.expert data")
    return TaskSwitch(switch.at, switch.env, data)
