"""Behavioral cloning from observation, BCO(alpha) (Torabi, Warnell & Stone, IJCAI 2018).

Learning from observation (LfO): the expert's actions are never read, only its state transitions
``(s, s')``. The agent learns the actions itself:

1. *pre-demonstration*: ``pre_steps`` environment steps of uniformly random actions (|I_pre|);
2. fit an inverse dynamics model ``a = g(s, s')`` (:mod:`rankgame.baselines.inverse_dynamics`) on all of
   the agent's transitions, whose actions it knows;
3. label every expert transition with the inferred action ``g(s, s')`` (clipped to the action box) and
   clone the labelled pairs with the tanh-Gaussian maximum likelihood of BC
   (:func:`~rankgame.baselines.cloning.tanh_gaussian_nll`);
4. *post-demonstration* (the alpha of BCO(alpha)): ``alpha * pre_steps`` environment steps of the current
   cloned policy (actions sampled from it), then 2. and 3. again on all the data so far; repeat.

The models are not re-initialized between fits: every fit continues from the last one's parameters and
Adam state, with ``pre_inverse_steps`` / ``pre_policy_steps`` gradient steps after phase 1 and
``inverse_steps`` / ``policy_steps`` after every round (the schedule of the OPOLO authors' BCO, see
:class:`~rankgame.baselines.cloning.CloningConfig`). BCO(0), the one-shot variant, is a run that stops
after phase 1 (``--steps`` equal to ``pre_steps``).
"""

from __future__ import annotations

import sys
from typing import Any

import jax
import numpy as np

from rankgame.baselines.cloning import ClonedPolicyTrainer, CloningConfig
from rankgame.baselines.inverse_dynamics import InverseDynamics
from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import make_env
from rankgame.envs.rollout import to_env_action
from rankgame.errors import NonFiniteError, RankGameError
from rankgame.scores import EVAL_COLUMNS

#: Columns of a BCO run's ``metrics.csv`` (``env_steps``: environment steps of interaction).
BCO_LOG_COLUMNS = (
    *EVAL_COLUMNS,
    "losses/bc",
    "losses/inverse",
    "grad_steps",
    "inverse_grad_steps",
)


def expert_transitions(trajectories: tuple[Trajectory, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The expert's states ``s`` and next states ``s'``, each ``(N, obs_dim)`` with ``N = sum T_i``."""
    obs = np.concatenate([t.obs[:-1] for t in trajectories]).astype(np.float32)
    next_obs = np.concatenate([t.obs[1:] for t in trajectories]).astype(np.float32)
    return obs, next_obs


class AgentTransitions:
    """Every transition the agent made, ``obs, next_obs (N, obs_dim)`` and normalized ``acts (N, act_dim)``,
    in host arrays that double when full."""

    def __init__(self, obs_dim: int, act_dim: int, capacity: int = 1024) -> None:
        shapes = {"obs": (obs_dim,), "acts": (act_dim,), "next_obs": (obs_dim,)}
        self._data = {name: np.zeros((capacity, *shape), np.float32) for name, shape in shapes.items()}
        self.size = 0

    def __len__(self) -> int:
        return self.size

    def add(self, obs: np.ndarray, acts: np.ndarray, next_obs: np.ndarray) -> None:
        if self.size == len(self._data["obs"]):
            self._data = {name: np.concatenate([array, np.zeros_like(array)]) for name, array in self._data.items()}
        for name, value in (("obs", obs), ("acts", acts), ("next_obs", next_obs)):
            self._data[name][self.size] = value
        self.size += 1

    def arrays(self) -> dict[str, np.ndarray]:
        """Views of the filled part, ``(N, ...)`` each."""
        return {name: array[: self.size] for name, array in self._data.items()}

    def state_dict(self) -> dict[str, np.ndarray]:
        return {f"bco/{name}": array.copy() for name, array in self.arrays().items()}

    def load_state_dict(self, arrays: dict[str, np.ndarray]) -> None:
        size = int(arrays["bco/obs"].shape[0])
        capacity = max(1024, 1 << max(size - 1, 0).bit_length())
        for name, array in self._data.items():
            stored = arrays[f"bco/{name}"]
            if stored.shape[1:] != array.shape[1:] or len(stored) != size:
                shape = stored.shape
                raise RankGameError(f"the checkpoint does not match this configuration (bco/{name} has shape {shape})")
            self._data[name] = np.zeros((capacity, *array.shape[1:]), np.float32)
            self._data[name][:size] = stored
        self.size = size


class BCOTrainer(ClonedPolicyTrainer):
    """BCO(alpha) as the :class:`~rankgame.run.Trainer` of ``rankgame train --method bco``.

    **A step is one environment step** of the agent (``env_steps``, as for the ranking game): uniformly
    random actions for steps ``1 .. pre_steps``, actions sampled from the cloned policy after that. The
    fits happen at round boundaries, inside the step that ends the round: at step ``pre_steps`` the
    statistics of the inverse model's inputs are set, then ``pre_inverse_steps`` inverse-model and
    ``pre_policy_steps`` policy gradient steps; at every step ``pre_steps + k * round_steps`` (``k >= 1``,
    ``round_steps = max(1, round(alpha * pre_steps))``) the same with ``inverse_steps`` and ``policy_steps``.
    ``grad_steps`` and ``inverse_grad_steps`` count the gradient steps of each model. Before step
    ``pre_steps`` the policy is the untrained actor.

    Training episodes are reset with seeds drawn from the trainer's NumPy generator (seeded ``seed``), and
    a checkpoint records the seed and start of the episode in progress; :meth:`restore` replays that
    episode's stored actions, so a resumed run goes on exactly as an uninterrupted one for any task whose
    steps are determined by the reset seed and the actions (all of rankgame's tasks; a mismatch is
    reported on stderr).

    Args:
        config, env_id, expert, n_expert, seed, eval_episodes: as
            :class:`~rankgame.baselines.cloning.ClonedPolicyTrainer`; only the expert's observations are
            read (its actions may be placeholders).
        steps: the run's length, if known: a run shorter than the pre-demonstration phase is refused,
            since it would never fit anything.

    Raises:
        RankGameError: as :class:`~rankgame.baselines.cloning.ClonedPolicyTrainer`, or ``steps < pre_steps``.
    """

    def __init__(
        self,
        config: CloningConfig,
        env_id: str,
        expert: TrajectoryFile,
        n_expert: int,
        seed: int,
        eval_episodes: int,
        steps: int | None = None,
    ) -> None:
        super().__init__(config, env_id, expert, n_expert, seed, eval_episodes)
        if steps is not None and steps < config.pre_steps:
            raise RankGameError(
                f"--steps {steps} is shorter than BCO's pre-demonstration phase ({config.pre_steps} steps, "
                "--cloning.pre-steps): nothing would be fit"
            )
        spec = self.spec
        self.env = make_env(env_id)
        self.expert_obs, self.expert_next_obs = expert_transitions(self.trajectories)
        self.inverse = InverseDynamics(
            spec.obs_dim,
            spec.act_dim,
            config.inverse_hidden_sizes,
            config.inverse_lr,
            config.inverse_weight_decay,
            config.batch_size,
            config.update_every,
        )
        self.inverse_state = self.inverse.init(jax.random.fold_in(jax.random.key(seed), 1))
        self.rng = np.random.default_rng(seed)
        self.data = AgentTransitions(spec.obs_dim, spec.act_dim)
        self.inverse_grad_steps = 0
        self.inverse_loss: float | None = None
        self._start_episode()

    def _start_episode(self) -> None:
        self.episode_seed = int(self.rng.integers(2**31 - 1))
        self.episode_start = self.env_steps
        self._obs, _ = self.env.reset(seed=self.episode_seed)

    def _action(self) -> np.ndarray:
        """The normalized action ``(act_dim,)`` of the next step."""
        act_dim = self.spec.act_dim
        if self.env_steps < self.config.pre_steps:
            return self.rng.uniform(-1.0, 1.0, act_dim).astype(np.float32)
        noise = self.rng.standard_normal((1, act_dim)).astype(np.float32)
        obs = np.asarray(self._obs, np.float32)[None]
        act = np.asarray(self.cloner.sac.act(self.state.params, obs, noise))[0]
        if not np.all(np.isfinite(act)):
            raise NonFiniteError("the policy's action")
        return act

    def step(self, step: int) -> None:
        """Environment step ``step`` and, when it ends the pre-demonstration phase or a round, the fits."""
        act = self._action()
        env_act = to_env_action(act, self.spec.act_low, self.spec.act_high)
        next_obs, rew, terminated, truncated, _ = self.env.step(env_act)
        if not (np.all(np.isfinite(next_obs)) and np.isfinite(rew)):
            raise NonFiniteError(f"the observation or reward of {self.spec.env_id}")
        self.data.add(self._obs, act, next_obs)
        self.env_steps += 1
        if terminated or truncated:
            self._start_episode()
        else:
            self._obs = next_obs
        cfg = self.config
        if self.env_steps == cfg.pre_steps:
            self.fit(cfg.pre_inverse_steps, cfg.pre_policy_steps)
        elif self.env_steps > cfg.pre_steps and (self.env_steps - cfg.pre_steps) % cfg.round_steps == 0:
            self.fit(cfg.inverse_steps, cfg.policy_steps)

    def fit(self, inverse_steps: int, policy_steps: int) -> None:
        """Fit the inverse model on all agent transitions, label the expert's transitions with it, and clone."""
        data = self.data.arrays()
        state = self.inverse.with_statistics(self.inverse_state, data["obs"], data["next_obs"])
        if inverse_steps:
            state, self.inverse_loss = self.inverse.fit(
                state, data["obs"], data["acts"], data["next_obs"], self.rng, inverse_steps
            )
        self.inverse_state = state
        self.inverse_grad_steps += inverse_steps
        labels = np.asarray(self.inverse.predict(state, self.expert_obs, self.expert_next_obs))
        if not np.all(np.isfinite(labels)):
            raise NonFiniteError("the inverse model's inferred actions")
        labels = np.clip(labels, -1.0, 1.0)
        if policy_steps:
            self.state, self.bc_loss = self.cloner.fit(self.state, self.expert_obs, labels, self.rng, policy_steps)
        self.grad_steps += policy_steps

    def training_metrics(self) -> dict[str, float]:
        """``losses/bc``, ``losses/inverse`` (mean losses of the last fit, once there was one), ``grad_steps``
        and ``inverse_grad_steps``."""
        metrics = {**super().training_metrics(), "inverse_grad_steps": self.inverse_grad_steps}
        return metrics if self.inverse_loss is None else {**metrics, "losses/inverse": self.inverse_loss}

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata, arrays = self._policy_checkpoint()
        metadata = {
            **metadata,
            "bco_rng": self.rng.bit_generator.state,
            "inverse_grad_steps": self.inverse_grad_steps,
            "inverse_loss": self.inverse_loss,
            "episode_seed": self.episode_seed,
            "episode_start": self.episode_start,
        }
        return metadata, {**arrays, **flatten_tree("inverse", self.inverse_state), **self.data.state_dict()}

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        """Inverse of :meth:`checkpoint`; the episode in progress is replayed from its reset seed."""
        self._policy_restore(metadata, arrays)
        self.inverse_state = unflatten_tree("inverse", arrays, self.inverse_state)
        self.data.load_state_dict(arrays)
        if len(self.data) != self.env_steps:
            raise RankGameError(f"the checkpoint holds {len(self.data)} transitions for {self.env_steps} steps")
        self.rng.bit_generator.state = metadata["bco_rng"]
        self.inverse_grad_steps = int(metadata["inverse_grad_steps"])
        loss = metadata["inverse_loss"]
        self.inverse_loss = None if loss is None else float(loss)
        self.episode_seed, self.episode_start = int(metadata["episode_seed"]), int(metadata["episode_start"])
        self._replay_episode()

    def _replay_episode(self) -> None:
        """Bring the environment back to the state of the episode in progress by replaying its actions."""
        self._obs, _ = self.env.reset(seed=self.episode_seed)
        data = self.data.arrays()
        for i in range(self.episode_start, self.env_steps):
            next_obs = self.env.step(to_env_action(data["acts"][i], self.spec.act_low, self.spec.act_high))[0]
            self._obs = next_obs
        if self.env_steps > self.episode_start and not np.array_equal(
            np.asarray(self._obs, np.float32), data["next_obs"][self.env_steps - 1]
        ):
            print(
                f"{self.spec.env_id}: the resumed episode does not replay exactly (the task is not deterministic); "
                "the run goes on from the replayed state",
                file=sys.stderr,
            )
