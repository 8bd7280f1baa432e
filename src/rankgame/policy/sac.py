"""Soft Actor-Critic (Haarnoja et al., 2018) as pure, jitted JAX functions.

The policy player of the ranking game. It knows nothing about rankings: every update receives a
*reward function* ``reward_fn(reward_params, batch) -> rews`` and relabels each sampled batch with it
inside the jitted update, so a learned reward that moves between updates is never stale.
:func:`env_reward` reads the environment's own reward from the batch (used to train experts).

Speed on a CPU comes from fusing many gradient steps into one XLA call: :meth:`SAC.update` runs
``lax.scan`` over a stack of pre-sampled batches of shape ``(n_updates, batch_size, ...)``.

Actions inside SAC live in the normalized box ``[-1, 1]^act_dim`` (the tanh range); the training
loop rescales them to the environment's bounds.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import flax.linen as nn
import flax.struct
import jax
import jax.numpy as jnp
import numpy as np
import optax

from rankgame.absorbing import absorbing_flag, absorbing_value, weighted_mean
from rankgame.errors import nonfinite_fields, require
from rankgame.nets import MLP
from rankgame.policy.critic_objectives import CriticObjective, SoftBellman

Batch = dict[str, jax.Array]
#: ``(reward_params, batch) -> rews`` of shape ``(batch_size,)``.
RewardFn = Callable[[Any, Batch], jax.Array]

LOG_STD_MIN = -20.0
LOG_STD_MAX = 2.0


@dataclass(frozen=True)
class SACConfig:
    """Hyperparameters of SAC. Defaults are the ``paper`` preset (SpinningUp's SAC, as in the paper)."""

    hidden_sizes: tuple[int, ...] = (256, 256)
    """Hidden layer widths of the actor and of each critic (ReLU)."""
    actor_lr: float = 1e-3
    """Adam learning rate of the actor."""
    critic_lr: float = 1e-3
    """Adam learning rate of the twin critics."""
    alpha_lr: float = 1e-3
    """Adam learning rate of the entropy temperature (only with learn_alpha)."""
    batch_size: int = 100
    """Transitions per gradient step."""
    gamma: float = 0.99
    """Discount factor."""
    polyak: float = 0.995
    """Target network averaging: target <- polyak * target + (1 - polyak) * online."""
    init_alpha: float = 0.2
    """Entropy temperature (its initial value when learned)."""
    learn_alpha: bool = False
    """Learn the temperature towards a target entropy instead of keeping it fixed."""
    target_entropy: float | None = None
    """Target policy entropy for the learned temperature; default -act_dim."""
    start_steps: int = 1000
    """Environment steps with uniformly random actions before the policy acts (SpinningUp's default is
    10000; 1000 is the one random episode of the authors' configurations)."""
    update_after: int = 1000
    """Environment steps before the first gradient step."""
    update_every: int = 50
    """Environment steps between update calls; each call fuses update_every gradient steps."""
    updates_per_step: float = 1.0
    """Gradient steps per environment step (update-to-data ratio)."""
    buffer_size: int = 1_000_000
    """Replay buffer capacity in transitions."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        checks = [
            (self.batch_size > 0, "batch_size must be positive"),
            (not nonfinite_fields(self), f"{', '.join(nonfinite_fields(self))} must be finite"),
            (0.0 <= self.gamma < 1.0, "gamma must lie in [0, 1)"),
            (0.0 <= self.polyak < 1.0, "polyak must lie in [0, 1)"),
            (self.init_alpha > 0.0, "init_alpha must be positive"),
            (min(self.actor_lr, self.critic_lr, self.alpha_lr) > 0.0, "learning rates must be positive"),
            (self.update_every > 0, "update_every must be positive"),
            (self.updates_per_step > 0.0, "updates_per_step must be positive"),
            (self.buffer_size >= self.batch_size, "buffer_size must be at least batch_size"),
            (all(h > 0 for h in self.hidden_sizes), "hidden_sizes must be positive"),
            (self.start_steps >= 0 and self.update_after >= 0, "start_steps and update_after must be >= 0"),
        ]
        require(checks)


#: Named presets. ``paper``: SpinningUp defaults used by the paper (App. C).
#: ``modern``: the batch size, learning rate and learned temperature most JAX/PyTorch SACs use today.
#: ``iq-learn``: the IQ-Learn authors' MuJoCo settings (their scripts' actor lr 3e-5, fixed temperature
#: 0.01, 256 agent rows per batch, to which IQ-Learn adds 256 expert rows, no random warm-up), the
#: default of ``--method iq-learn``.
SAC_PRESETS: dict[str, SACConfig] = {
    "paper": SACConfig(),
    "modern": SACConfig(actor_lr=3e-4, critic_lr=3e-4, alpha_lr=3e-4, batch_size=256, init_alpha=1.0, learn_alpha=True),
    "iq-learn": SACConfig(
        actor_lr=3e-5,
        critic_lr=3e-4,
        alpha_lr=3e-4,
        batch_size=256,
        init_alpha=0.01,
        start_steps=0,
        update_after=1280,
    ),
}


def sac_preset(name: str, **overrides: Any) -> SACConfig:
    """Return the named preset with some fields replaced."""
    if name not in SAC_PRESETS:
        raise ValueError(f"unknown SAC preset {name!r}; choose from {', '.join(SAC_PRESETS)}")
    return replace(SAC_PRESETS[name], **overrides)


class Actor(nn.Module):
    """Tanh-squashed Gaussian policy head: ``obs (B, obs_dim) -> (mean, log_std)``, each ``(B, act_dim)``."""

    hidden_sizes: tuple[int, ...]
    act_dim: int

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        out = MLP(self.hidden_sizes, 2 * self.act_dim)(obs)
        mean, log_std = jnp.split(out, 2, axis=-1)
        return mean, jnp.clip(log_std, LOG_STD_MIN, LOG_STD_MAX)


class TwinCritic(nn.Module):
    """Two independent Q networks evaluated together: ``(obs, acts) -> q`` of shape ``(2, B)``."""

    hidden_sizes: tuple[int, ...]

    @nn.compact
    def __call__(self, obs: jax.Array, acts: jax.Array) -> jax.Array:
        batched = nn.vmap(
            MLP,
            variable_axes={"params": 0},
            split_rngs={"params": True},
            in_axes=None,
            out_axes=0,
            axis_size=2,
        )
        return batched(self.hidden_sizes, 1)(jnp.concatenate([obs, acts], axis=-1))[..., 0]


def squashed_gaussian_sample(mean: jax.Array, log_std: jax.Array, noise: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Reparameterized tanh-Gaussian sample and its log-probability.

    Args:
        mean, log_std, noise: ``(B, act_dim)``; ``noise`` is standard normal.
    Returns:
        ``acts (B, act_dim)`` in ``(-1, 1)`` and ``logp (B,)`` including the tanh Jacobian.
    """
    pre_tanh = mean + jnp.exp(log_std) * noise
    normal_logp = -0.5 * (noise**2 + 2.0 * log_std + jnp.log(2.0 * jnp.pi))
    # log(1 - tanh(u)^2) written stably as 2 (log 2 - u - softplus(-2u)).
    log_jacobian = 2.0 * (jnp.log(2.0) - pre_tanh - jax.nn.softplus(-2.0 * pre_tanh))
    return jnp.tanh(pre_tanh), jnp.sum(normal_logp - log_jacobian, axis=-1)


def env_reward(_reward_params: Any, batch: Batch) -> jax.Array:
    """Reward function that returns the environment's reward stored in ``batch["rews"]`` ``(B,)``."""
    return batch["rews"]


@flax.struct.dataclass
class SACState:
    """Everything SAC learns, as one pytree (saved, restored and carried through ``lax.scan``)."""

    actor_params: Any
    critic_params: Any
    target_critic_params: Any
    log_alpha: jax.Array
    actor_opt_state: Any
    critic_opt_state: Any
    alpha_opt_state: Any
    key: jax.Array
    n_updates: jax.Array


@dataclass
class SAC:
    """SAC for one observation/action size. Build once; :meth:`update` and :meth:`act` are jitted.

    Attributes:
        reward_fn: how each sampled batch is labelled with rewards (static: changing it recompiles).
        absorbing: the last observation entry is a DAC-style absorbing flag (see
            :mod:`rankgame.absorbing`). The absorbing state ``s_abs`` loops on itself whatever the
            action, so its value is known exactly, ``r(s_abs) / (1 - gamma)``: the critic's target
            uses it for every transition into ``s_abs`` instead of bootstrapping the critic there, and
            the actor and temperature losses ignore rows that start in ``s_abs``. Bootstrapping the
            self-loop lets the critic carry the value of real states over to ``s_abs`` (no action
            there is ever taken by the policy), which makes terminating look as good as surviving.
            The closed form has no entropy bonus: the policy makes no choice in ``s_abs``, just as
            plain SAC adds none after a terminal transition.
        critic_objective: what the critic minimizes (:mod:`rankgame.policy.critic_objectives`): SAC's soft
            Bellman error by default, IQ-Learn's inverse soft-Q objective for ``iq-learn``.
    """

    obs_dim: int
    act_dim: int
    config: SACConfig
    reward_fn: RewardFn = env_reward
    absorbing: bool = False
    critic_objective: CriticObjective = field(default_factory=SoftBellman)
    actor: Actor = field(init=False)
    critic: TwinCritic = field(init=False)

    def __post_init__(self) -> None:
        self.config.validate()
        self.actor = Actor(self.config.hidden_sizes, self.act_dim)
        self.critic = TwinCritic(self.config.hidden_sizes)
        cfg = self.config
        self.target_entropy = float(-self.act_dim if cfg.target_entropy is None else cfg.target_entropy)
        self.actor_tx = optax.adam(cfg.actor_lr)
        self.critic_tx = optax.adam(cfg.critic_lr)
        self.alpha_tx = optax.adam(cfg.alpha_lr)
        self.update = jax.jit(self._update_many, donate_argnums=(0,))
        self.act = jax.jit(self._act)

    def init(self, key: jax.Array) -> SACState:
        """Fresh parameters and optimizer states from a ``jax.random`` key."""
        k_actor, k_critic, k_state = jax.random.split(key, 3)
        obs = jnp.zeros((1, self.obs_dim), jnp.float32)
        acts = jnp.zeros((1, self.act_dim), jnp.float32)
        actor_params = self.actor.init(k_actor, obs)
        critic_params = self.critic.init(k_critic, obs, acts)
        log_alpha = jnp.asarray(np.log(self.config.init_alpha), jnp.float32)
        return SACState(
            actor_params=actor_params,
            critic_params=critic_params,
            target_critic_params=jax.tree.map(jnp.copy, critic_params),
            log_alpha=log_alpha,
            actor_opt_state=self.actor_tx.init(actor_params),
            critic_opt_state=self.critic_tx.init(critic_params),
            alpha_opt_state=self.alpha_tx.init(log_alpha),
            key=k_state,
            n_updates=jnp.zeros((), jnp.int32),
        )

    def _act(self, actor_params: Any, obs: jax.Array, noise: jax.Array) -> jax.Array:
        """Normalized actions ``(B, act_dim)`` for ``obs (B, obs_dim)``; ``noise = 0`` gives the mean action."""
        mean, log_std = self.actor.apply(actor_params, obs)
        return jnp.tanh(mean + jnp.exp(log_std) * noise)

    def losses(self, state: SACState, batch: Batch, reward_params: Any) -> tuple[SACState, dict[str, jax.Array]]:
        """One SAC gradient step on ``batch`` (arrays of leading size ``batch_size``).

        Batch keys: ``obs (B, obs_dim)``, ``acts (B, act_dim)`` normalized, ``next_obs (B, obs_dim)``,
        ``dones (B,)`` 1.0 where the transition ended in a true terminal state (not a time limit),
        plus whatever ``reward_fn`` reads.
        """
        cfg = self.config
        key, k_critic, k_pi = jax.random.split(state.key, 3)
        alpha = jnp.exp(state.log_alpha)
        objective = self.critic_objective
        prepared = objective.prepare(self, state, batch, reward_params, k_critic, alpha)
        # Rows whose actor/temperature loss counts: all, or those not starting in s_abs.
        live = 1.0 - absorbing_flag(batch["obs"]) if self.absorbing else jnp.ones(batch["obs"].shape[0])

        def critic_loss_fn(critic_params: Any) -> tuple[jax.Array, tuple[jax.Array, dict[str, jax.Array]]]:
            return objective.loss(self, critic_params, batch, prepared)

        (critic_loss, (q, critic_metrics)), critic_grads = jax.value_and_grad(critic_loss_fn, has_aux=True)(
            state.critic_params
        )
        critic_updates, critic_opt_state = self.critic_tx.update(critic_grads, state.critic_opt_state)
        critic_params = optax.apply_updates(state.critic_params, critic_updates)

        noise = jax.random.normal(k_pi, (batch["obs"].shape[0], self.act_dim))

        def actor_loss_fn(actor_params: Any) -> tuple[jax.Array, jax.Array]:
            mean, log_std = self.actor.apply(actor_params, batch["obs"])
            acts, logp = squashed_gaussian_sample(mean, log_std, noise)
            q_pi = jnp.min(self.critic.apply(critic_params, batch["obs"], acts), axis=0)
            return weighted_mean(alpha * logp - q_pi, live), logp

        (actor_loss, logp), actor_grads = jax.value_and_grad(actor_loss_fn, has_aux=True)(state.actor_params)
        actor_updates, actor_opt_state = self.actor_tx.update(actor_grads, state.actor_opt_state)
        actor_params = optax.apply_updates(state.actor_params, actor_updates)

        log_alpha, alpha_opt_state = state.log_alpha, state.alpha_opt_state
        entropy_gap = jax.lax.stop_gradient(weighted_mean(logp, live) + self.target_entropy)
        if cfg.learn_alpha:
            alpha_grad = -entropy_gap  # d/d(log_alpha) of -log_alpha * (logp + target_entropy)
            alpha_updates, alpha_opt_state = self.alpha_tx.update(alpha_grad, state.alpha_opt_state)
            log_alpha = optax.apply_updates(state.log_alpha, alpha_updates)

        target_critic_params = optax.incremental_update(critic_params, state.target_critic_params, 1.0 - cfg.polyak)
        new_state = SACState(
            actor_params=actor_params,
            critic_params=critic_params,
            target_critic_params=target_critic_params,
            log_alpha=log_alpha,
            actor_opt_state=actor_opt_state,
            critic_opt_state=critic_opt_state,
            alpha_opt_state=alpha_opt_state,
            key=key,
            n_updates=state.n_updates + 1,
        )
        metrics = {
            "losses/critic": critic_loss,
            "losses/actor": actor_loss,
            "losses/alpha": alpha,
            "losses/entropy": -weighted_mean(logp, live),
            "losses/q": jnp.mean(q),
            **critic_metrics,
        }
        return new_state, metrics

    def absorbing_value(self, reward_params: Any) -> jax.Array:
        """Value ``()`` of the absorbing state, ``r(s_abs) / (1 - gamma)``: it loops on itself forever."""
        return absorbing_value(self.reward_fn, reward_params, self.obs_dim, self.act_dim, self.config.gamma)

    def _update_many(
        self, state: SACState, batches: Batch, reward_params: Any
    ) -> tuple[SACState, dict[str, jax.Array]]:
        """``n`` fused gradient steps over ``batches`` of shape ``(n, batch_size, ...)``; metrics averaged."""

        def step(carry: SACState, batch: Batch) -> tuple[SACState, dict[str, jax.Array]]:
            return self.losses(carry, batch, reward_params)

        state, metrics = jax.lax.scan(step, state, batches)
        return state, jax.tree.map(jnp.mean, metrics)
