"""Behavior cloning (BC): a tanh-squashed Gaussian policy fit by maximum likelihood on expert (s, a).

BC (Pomerleau, 1991, ALVINN; Bain & Sammut, 1995, "A framework for behavioural cloning") treats the
expert's state-action pairs as i.i.d. supervised data and maximizes the likelihood of the expert's
actions under the policy. It needs the expert's actions (learning from demonstration, LfD) and no
interaction with the environment at all.

The policy is the SAC :class:`~rankgame.policy.sac.Actor` (``obs -> (mean, log_std)``, action
``tanh(mean + exp(log_std) * noise)`` in the normalized box ``[-1, 1]^act_dim``), so a cloned policy is
saved with :func:`~rankgame.policy.io.save_policy`, read back with
:func:`~rankgame.policy.io.load_policy` and run by ``rankgame evaluate`` like any SAC actor; the SAC
object built for it (:attr:`PolicyCloner.sac`) only carries the actor's shape and acts.

Updates are pure jitted functions: :meth:`PolicyCloner.update` fuses a stack of pre-sampled batches of
shape ``(n, batch_size, ...)`` into ``n`` Adam steps with ``lax.scan`` (as :class:`~rankgame.policy.sac.SAC`
does), so a CPU spends its time on arithmetic rather than on dispatch.

This module also holds what BC and BCO (:mod:`rankgame.baselines.bco`) share: :class:`CloningConfig`,
the loss :func:`tanh_gaussian_nll`, the fitting helper :func:`fused_fit`, and
:class:`ClonedPolicyTrainer`, the evaluation, policy files and progress bar of both trainers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.checkpoint import flatten_tree, unflatten_tree
from rankgame.data.trajectories import Trajectory, TrajectoryFile
from rankgame.envs.make import EnvSpec, env_spec, make_env
from rankgame.envs.rollout import (
    EVAL_SEED_OFFSET,
    PolicyFn,
    to_normalized_action,
)
from rankgame.errors import NonFiniteError, RankGameError, nonfinite_fields, require
from rankgame.policy.io import save_policy
from rankgame.policy.learner import make_policy_fn
from rankgame.policy.sac import SAC, SACConfig
from rankgame.run import POLICY_NAME
from rankgame.scores import EVAL_COLUMNS, ScoreScale, score_postfix

#: ``|a|`` of a normalized action is clipped to at most this before ``atanh`` in :func:`tanh_gaussian_nll`.
#: Expert actions often sit exactly on the bounds (a saturated controller, or a tanh policy rounded to
#: float32), where ``atanh`` is infinite; ``1 - 1e-5`` maps to the pre-tanh value ``atanh = 6.1`` and keeps
#: the tanh Jacobian term ``log(1 - a^2)`` at ``log(2e-5) = -10.8`` instead of minus infinity. It is
#: representable in float32 (the spacing below 1 is ``6e-8``).
ACTION_CLIP = 1.0 - 1e-5

#: Expert actions may leave the action box by this much (in normalized units) before a file is refused:
#: float rounding of actions recorded on the bounds, not actions in other units.
ACTION_BOX_TOLERANCE = 1e-3

Batch = dict[str, jax.Array]


@dataclass(frozen=True)
class CloningConfig:
    """Hyperparameters of behavior cloning (BC) and of behavioral cloning from observation, BCO(alpha).

    Where the defaults come from: the BCO values (``pre_steps``, ``alpha``, the gradient steps of each
    fit, the inverse model's size, learning rate and L2 penalty, the policy's learning rate) are those of
    the BCO baseline in the OPOLO authors' code (illidanlab/opolo-code, ``stable_baselines/td3/td3bco.py``
    with ``hyperparams/td3bco.yml`` for the MuJoCo tasks and ``stable_baselines/gail/idm.py``): a round every
    ``train_freq = 1000`` environment steps, ``alpha = 0.1``, so ``1000 / 0.1 = 10000`` pre-demonstration
    steps, 100 inverse-model and 100 policy gradient steps per round, ``100 / 0.1 = 1000`` inverse-model
    steps after the pre-demonstration phase, an inverse model of two 256-unit layers with Adam at 3e-4
    and an L2 penalty of 1e-3, and the policy's Adam at 1e-3. Our own choices: the batch size of 256 (OPOLO:
    100), the policy's two 256-unit layers (the SAC actor of this package; OPOLO: 400 and 300), ReLU in the
    inverse model (OPOLO: tanh), 1000 policy gradient steps after the pre-demonstration phase (OPOLO trains
    no policy until its first round), no L2 penalty on the policy, and the fusing of 100 gradient steps.
    Torabi et al. (2018) give no network sizes or step counts for the MuJoCo tasks that would override these.
    """

    hidden_sizes: tuple[int, ...] = (256, 256)
    """Hidden layer widths of the cloned policy (ReLU; the SAC actor, so saved policies run with `rankgame
    evaluate`)."""
    lr: float = 1e-3
    """Adam learning rate of the policy (OPOLO's BCO: 1e-3)."""
    batch_size: int = 256
    """Samples per gradient step: expert pairs for the policy, agent transitions for the inverse model."""
    weight_decay: float = 0.0
    """L2 penalty on the policy's parameters: weight_decay * params is added to the gradient before Adam."""
    update_every: int = 100
    """Gradient steps fused into one jitted call; BC runs its gradient steps in blocks of this many."""
    pre_steps: int = 10_000
    """BCO: environment steps of uniformly random actions before the first fit, |I_pre| (OPOLO: 1000 / 0.1)."""
    alpha: float = 0.1
    """BCO(alpha): environment steps of the cloned policy per post-demonstration round, as a fraction of
    pre_steps (OPOLO: 0.1). BCO(0), the paper's one-shot variant, is a run of --steps equal to pre_steps."""
    pre_inverse_steps: int = 1000
    """BCO: gradient steps of the inverse model at the end of the pre-demonstration phase (OPOLO: 100 / 0.1)."""
    pre_policy_steps: int = 1000
    """BCO: gradient steps of the policy at the end of the pre-demonstration phase."""
    inverse_steps: int = 100
    """BCO: gradient steps of the inverse model at the end of every post-demonstration round (OPOLO: 100)."""
    policy_steps: int = 100
    """BCO: gradient steps of the policy at the end of every post-demonstration round (OPOLO: 100)."""
    inverse_hidden_sizes: tuple[int, ...] = (256, 256)
    """BCO: hidden layer widths of the inverse dynamics model (ReLU; OPOLO: 256, 256)."""
    inverse_lr: float = 3e-4
    """BCO: Adam learning rate of the inverse dynamics model (OPOLO: 3e-4)."""
    inverse_weight_decay: float = 1e-3
    """BCO: L2 penalty on the inverse model's parameters, added to its gradient before Adam (OPOLO: 1e-3)."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        steps = (self.update_every, self.pre_steps, self.pre_inverse_steps, self.pre_policy_steps)
        checks = [
            (not nonfinite_fields(self), f"{', '.join(nonfinite_fields(self))} must be finite"),
            (self.batch_size > 0, "batch_size must be positive"),
            (self.lr > 0.0 and self.inverse_lr > 0.0, "learning rates must be positive"),
            (self.weight_decay >= 0.0 and self.inverse_weight_decay >= 0.0, "weight decays must be >= 0"),
            (min(steps) > 0, "update_every, pre_steps, pre_inverse_steps and pre_policy_steps must be positive"),
            (self.inverse_steps >= 0 and self.policy_steps >= 0, "inverse_steps and policy_steps must be >= 0"),
            (self.alpha > 0.0, "alpha must be positive (BCO(0) is a run of --steps equal to pre_steps)"),
            (len(self.hidden_sizes) > 0 and all(h > 0 for h in self.hidden_sizes), "hidden_sizes must be positive"),
            (
                len(self.inverse_hidden_sizes) > 0 and all(h > 0 for h in self.inverse_hidden_sizes),
                "inverse_hidden_sizes must be positive",
            ),
        ]
        require(checks)

    @property
    def round_steps(self) -> int:
        """Environment steps of one BCO post-demonstration round, ``alpha * pre_steps`` (at least 1)."""
        return max(1, round(self.alpha * self.pre_steps))


def clipped_atanh(acts: jax.Array) -> jax.Array:
    """``atanh`` of normalized actions ``(..., act_dim)`` clipped to ``[-ACTION_CLIP, ACTION_CLIP]``."""
    return jnp.arctanh(jnp.clip(acts, -ACTION_CLIP, ACTION_CLIP))


def tanh_gaussian_nll(mean: jax.Array, log_std: jax.Array, acts: jax.Array) -> jax.Array:
    """Negative log-likelihood of normalized actions under the tanh-squashed Gaussian policy.

    With ``u = atanh(a)`` (clipped, see :data:`ACTION_CLIP`) and ``a = tanh(u)``, ``u ~ N(mean, std^2)``:
    ``-log p(a) = sum_i [ (u_i - mean_i)^2 / (2 std_i^2) + log std_i + log(2 pi) / 2 + log(1 - a_i^2) ]``;
    the last term is the tanh Jacobian (written stably as ``2 (log 2 - u - softplus(-2u))``, as in
    :func:`~rankgame.policy.sac.squashed_gaussian_sample`).

    Args:
        mean, log_std: ``(B, act_dim)``, the actor's outputs.
        acts: ``(B, act_dim)`` actions in the normalized box ``[-1, 1]``.
    Returns:
        ``(B,)`` negative log-likelihoods.
    """
    pre_tanh = clipped_atanh(acts)
    z = (pre_tanh - mean) * jnp.exp(-log_std)
    normal_logp = -0.5 * (z**2 + 2.0 * log_std + jnp.log(2.0 * jnp.pi))
    log_jacobian = 2.0 * (jnp.log(2.0) - pre_tanh - jax.nn.softplus(-2.0 * pre_tanh))
    return -jnp.sum(normal_logp - log_jacobian, axis=-1)


def l2_adam(lr: float, weight_decay: float) -> optax.GradientTransformation:
    """Adam whose gradient first gets ``weight_decay * params`` added: the gradient of the L2 penalty
    ``weight_decay / 2 * ||params||^2`` (the coupled penalty of OPOLO's inverse model)."""
    if weight_decay == 0.0:
        return optax.adam(lr)
    return optax.chain(optax.add_decayed_weights(weight_decay), optax.adam(lr))


#: ``update(state, batches) -> (state, mean loss ())`` over batches of shape ``(n, batch_size, ...)``.
FusedUpdate = Callable[[Any, dict[str, np.ndarray]], tuple[Any, jax.Array]]


def fused_fit(
    update: FusedUpdate,
    state: Any,
    data: dict[str, np.ndarray],
    rng: np.random.Generator,
    n_steps: int,
    batch_size: int,
    chunk: int,
    what: str = "the cloning loss",
) -> tuple[Any, float]:
    """``n_steps`` gradient steps on batches drawn uniformly (with replacement) from ``data``.

    Args:
        update: a fused update (see :data:`FusedUpdate`).
        data: arrays of equal leading size ``N`` (``(N, ...)`` each).
        rng: draws the batch indices ``(n, batch_size)`` of each call.
        chunk: gradient steps per jitted call (the last call may fuse fewer, which compiles once more).
        what: names the loss in the error.
    Returns:
        The new state and the mean loss over all the steps (NaN when ``n_steps`` is 0).
    Raises:
        NonFiniteError: if a call's loss is not finite.
    """
    size = len(next(iter(data.values())))
    total, done = 0.0, 0
    while done < n_steps:
        n = min(chunk, n_steps - done)
        idx = rng.integers(0, size, size=(n, batch_size))
        state, loss = update(state, {name: array[idx] for name, array in data.items()})
        value = float(loss)
        if not np.isfinite(value):
            raise NonFiniteError(what)
        total, done = total + value * n, done + n
    return state, total / n_steps if n_steps else float("nan")


@flax.struct.dataclass
class CloneState:
    """The cloned policy as one pytree: actor parameters, Adam state, gradient steps taken."""

    params: Any
    opt_state: Any
    n_updates: jax.Array


class PolicyCloner:
    """Maximum-likelihood fit of the SAC actor to (state, normalized action) pairs.

    Args:
        obs_dim, act_dim: sizes of one observation and one action.
        config: the network, learning rate, L2 penalty, batch size and fusing.
    """

    def __init__(self, obs_dim: int, act_dim: int, config: CloningConfig) -> None:
        self.config = config
        self.sac = SAC(obs_dim, act_dim, SACConfig(hidden_sizes=tuple(config.hidden_sizes)))
        """Carries the actor's shape for :func:`~rankgame.policy.io.save_policy` and acts (``sac.act``)."""
        self.actor = self.sac.actor
        self.obs_dim, self.act_dim = obs_dim, act_dim
        self.tx = l2_adam(config.lr, config.weight_decay)
        self.update: FusedUpdate = jax.jit(self._update_many)

    def init(self, key: jax.Array) -> CloneState:
        """Fresh actor parameters (the SAC actor's initialization) and Adam state."""
        return jax.jit(self._init)(key)  # one compiled program: much faster than op-by-op on a CPU

    def _init(self, key: jax.Array) -> CloneState:
        params = self.actor.init(key, jnp.zeros((1, self.obs_dim), jnp.float32))
        return CloneState(params=params, opt_state=self.tx.init(params), n_updates=jnp.zeros((), jnp.int32))

    def loss(self, params: Any, batch: Batch) -> jax.Array:
        """Mean :func:`tanh_gaussian_nll` ``()`` of ``batch["acts"] (B, act_dim)`` given ``batch["obs"]
        (B, obs_dim)``."""
        mean, log_std = self.actor.apply(params, batch["obs"])
        return jnp.mean(tanh_gaussian_nll(mean, log_std, batch["acts"]))

    def _update_many(self, state: CloneState, batches: Batch) -> tuple[CloneState, jax.Array]:
        """``n`` Adam steps over ``batches`` ``obs (n, B, obs_dim)``, ``acts (n, B, act_dim)``; mean loss ``()``."""

        def one(carry: CloneState, batch: Batch) -> tuple[CloneState, jax.Array]:
            loss, grads = jax.value_and_grad(self.loss)(carry.params, batch)
            updates, opt_state = self.tx.update(grads, carry.opt_state, carry.params)
            params = optax.apply_updates(carry.params, updates)
            return CloneState(params=params, opt_state=opt_state, n_updates=carry.n_updates + 1), loss

        state, losses = jax.lax.scan(one, state, batches)
        return state, jnp.mean(losses)

    def fit(
        self, state: CloneState, obs: np.ndarray, acts: np.ndarray, rng: np.random.Generator, n_steps: int
    ) -> tuple[CloneState, float]:
        """``n_steps`` gradient steps on ``obs (N, obs_dim)`` and normalized ``acts (N, act_dim)``; mean loss."""
        data = {"obs": obs, "acts": acts}
        cfg = self.config
        return fused_fit(self.update, state, data, rng, n_steps, cfg.batch_size, cfg.update_every)

    def policy(
        self,
        state: CloneState,
        spec: EnvSpec,
        rng: np.random.Generator | None = None,
        deterministic: bool = True,
    ) -> PolicyFn:
        """The policy as ``obs (obs_dim,) -> action (act_dim,)`` in environment units (mean action when
        deterministic)."""
        return make_policy_fn(self.sac, state.params, spec.act_low, spec.act_high, rng, deterministic)


def expert_state_actions(trajectories: Sequence[Trajectory], spec: EnvSpec) -> tuple[np.ndarray, np.ndarray]:
    """The expert's states ``(N, obs_dim)`` and actions ``(N, act_dim)`` in the normalized box, ``N = sum T_i``.

    Raises:
        RankGameError: the data has no usable actions: another action size than the task's, no nonzero
            action at all (an observation-only file, whose actions are placeholders), or actions outside
            the task's action box (by more than :data:`ACTION_BOX_TOLERANCE`: other units).
    """
    act_dim = trajectories[0].acts.shape[1]
    if act_dim != spec.act_dim:
        raise RankGameError(
            f"BC needs the expert's actions: the data has act_dim={act_dim}, {spec.env_id} has {spec.act_dim}"
        )
    obs = np.concatenate([t.obs[:-1] for t in trajectories]).astype(np.float32)
    raw = np.concatenate([t.acts for t in trajectories]).astype(np.float32)
    if not np.any(raw):
        raise RankGameError(
            "BC needs the expert's actions, but every action in the expert data is 0 (observation-only data); "
            "use bco, which needs only observations"
        )
    acts = to_normalized_action(raw, spec.act_low, spec.act_high)
    if not np.all(np.isfinite(acts)):
        raise RankGameError(f"BC needs a bounded action box; {spec.env_id} has an infinite action bound")
    worst = float(np.max(np.abs(acts)))
    if worst > 1.0 + ACTION_BOX_TOLERANCE:
        raise RankGameError(
            f"BC needs the expert's actions in {spec.env_id}'s action box, but some are {worst - 1:.3g} box "
            "half-widths outside it (actions recorded in other units?)"
        )
    return obs, np.clip(acts, -1.0, 1.0).astype(np.float32)


def expert_trajectories(
    expert: TrajectoryFile, n_expert: int, spec: EnvSpec, what: str = "expert data"
) -> tuple[Trajectory, ...]:
    """The first ``n_expert`` trajectories of ``expert``, checked against the task's observation size."""
    if n_expert < 1:
        raise RankGameError(f"--expert-trajectories must be positive (got {n_expert})")
    if len(expert.trajectories) < n_expert:
        raise RankGameError(
            f"{what} holds {len(expert.trajectories)} trajectories; --expert-trajectories asks for {n_expert}"
        )
    if expert.obs_dim != spec.obs_dim:
        raise RankGameError(f"{what} has obs_dim={expert.obs_dim}; {spec.env_id} has obs_dim={spec.obs_dim}")
    return expert.trajectories[:n_expert]


#: Columns of a BC run's ``metrics.csv`` (``env_steps`` is the harness's step: a gradient step for BC).
BC_LOG_COLUMNS = (
    *EVAL_COLUMNS,
    "losses/bc",
    "grad_steps",
)


class ClonedPolicyTrainer:
    """What BC and BCO share as :class:`~rankgame.run.Trainer`: the evaluation environment, the normalized
    score, the cloned policy (:attr:`state`, fit by :attr:`cloner`), its file and progress-bar fields.

    Args:
        config: the hyperparameters (validated here).
        env_id: the task the policy is evaluated on.
        expert: the expert data; its first ``n_expert`` trajectories are imitated, and the mean return of
            all of them (with the metadata's ``random_return_mean``, else a measured one) scales the score.
        n_expert: how many expert trajectories to imitate.
        seed: seeds the parameters, the batches and (BCO) the interaction.
        eval_episodes: episodes per evaluation, reset from ``seed + EVAL_SEED_OFFSET + i``.

    Raises:
        RankGameError: bad settings, an unknown task, or expert data that does not fit the task.
    """

    def __init__(
        self, config: CloningConfig, env_id: str, expert: TrajectoryFile, n_expert: int, seed: int, eval_episodes: int
    ) -> None:
        try:
            config.validate()
        except ValueError as exc:
            raise RankGameError(f"bad cloning setting: {exc}") from None
        if eval_episodes < 1:
            raise RankGameError(f"--eval-episodes must be positive (got {eval_episodes})")
        self.config, self.env_id, self.seed, self.eval_episodes = config, env_id, seed, eval_episodes
        self.command = ""
        """The command line recorded in saved policies."""
        self.eval_env = make_env(env_id)
        self.spec = env_spec(self.eval_env)
        self.trajectories = expert_trajectories(expert, n_expert, self.spec)
        self.cloner = PolicyCloner(self.spec.obs_dim, self.spec.act_dim, config)
        self.state = self.cloner.init(jax.random.key(seed))
        self.env_steps = 0
        """The harness's step counter (see the trainer's class docstring for what one step is)."""
        self.grad_steps = 0
        """Gradient steps of the policy so far."""
        self.bc_loss: float | None = None
        self.scale = ScoreScale.of(expert, self.eval_env, seed)

    def policy(self, deterministic: bool = True, rng: np.random.Generator | None = None) -> PolicyFn:
        """The current cloned policy in environment units (its mean action when deterministic)."""
        return self.cloner.policy(self.state, self.spec, rng, deterministic)

    def can_checkpoint(self, step: int) -> bool:
        """Always: a checkpoint at any step resumes exactly."""
        return True

    def evaluate(self) -> dict[str, float]:
        """The deterministic policy's evaluation row (:meth:`~rankgame.scores.ScoreScale.evaluate`)."""
        return self.scale.evaluate(self.eval_env, self.policy(), self.eval_episodes, self.seed + EVAL_SEED_OFFSET)

    def training_metrics(self) -> dict[str, float]:
        """``losses/bc`` (mean negative log-likelihood of the last fit, once there was one) and ``grad_steps``."""
        metrics: dict[str, float] = {"grad_steps": self.grad_steps}
        return metrics if self.bc_loss is None else {"losses/bc": self.bc_loss, **metrics}

    def postfix(self, row: dict[str, float]) -> dict[str, str]:
        return score_postfix(row)

    def save_policies(self, out: Path, step: int, row: dict[str, float]) -> None:
        """Write the current policy to ``out / policy.msgpack`` for ``rankgame evaluate``."""
        save_policy(
            out / POLICY_NAME,
            self.cloner.sac,
            jax.device_get(self.state.params),
            self.env_id,
            self.spec.act_low,
            self.spec.act_high,
            command=self.command,
            env_steps=step,
            grad_steps=self.grad_steps,
            eval_return=row["eval_return"],
        )

    def _policy_checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata = {"env_steps": self.env_steps, "grad_steps": self.grad_steps, "bc_loss": self.bc_loss}
        return metadata, flatten_tree("bc", self.state)

    def _policy_restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self.state = unflatten_tree("bc", arrays, self.state)
        self.env_steps, self.grad_steps = int(metadata["env_steps"]), int(metadata["grad_steps"])
        self.bc_loss = None if metadata["bc_loss"] is None else float(metadata["bc_loss"])


class BCTrainer(ClonedPolicyTrainer):
    """Behavior cloning as the :class:`~rankgame.run.Trainer` of ``rankgame train --method bc``.

    **A step is one gradient step of the policy.** The gradient steps run in fused blocks of
    ``config.update_every``: step ``k`` runs the block of steps ``k - update_every + 1 .. k`` when ``k`` is a
    multiple of ``update_every`` and nothing otherwise, so after step ``k`` exactly
    ``update_every * floor(k / update_every)`` gradient steps are done (``grad_steps``; choose ``--steps``
    and ``--eval-every`` as multiples of ``update_every``). BC never interacts with the environment: the
    harness's ``env_steps`` (the attribute and the ``metrics.csv`` column, which the harness resumes from)
    counts these training steps, not environment steps; only evaluation episodes touch the task.

    Each gradient step draws ``batch_size`` expert pairs uniformly with replacement (a NumPy generator
    seeded ``[seed, 1]``) and takes an Adam step on their mean :func:`tanh_gaussian_nll`. Arguments as
    :class:`ClonedPolicyTrainer`.

    Raises:
        RankGameError: as :class:`ClonedPolicyTrainer`, and for expert data without usable actions
            (:func:`expert_state_actions`).
    """

    def __init__(
        self, config: CloningConfig, env_id: str, expert: TrajectoryFile, n_expert: int, seed: int, eval_episodes: int
    ) -> None:
        super().__init__(config, env_id, expert, n_expert, seed, eval_episodes)
        self.obs, self.acts = expert_state_actions(self.trajectories, self.spec)
        self.rng = np.random.default_rng([seed, 1])

    def step(self, step: int) -> None:
        """Training step ``step``: the fused block of gradient steps that ends at it, if one does."""
        self.env_steps = step
        if step % self.config.update_every == 0:
            n = self.config.update_every
            self.state, self.bc_loss = self.cloner.fit(self.state, self.obs, self.acts, self.rng, n)
            self.grad_steps += n

    def checkpoint(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        metadata, arrays = self._policy_checkpoint()
        return {**metadata, "bc_rng": self.rng.bit_generator.state}, arrays

    def restore(self, metadata: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        self._policy_restore(metadata, arrays)
        self.rng.bit_generator.state = metadata["bc_rng"]
