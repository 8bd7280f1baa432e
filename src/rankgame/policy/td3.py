"""TD3 (Fujimoto et al., 2018) as pure, jitted JAX functions: the backbone of OPOLO's policy player.

A deterministic actor ``pi(s) = tanh(mu(s))`` and twin critics, with the critic's and the actor's
objectives as named pieces (:mod:`rankgame.policy.td3_objectives`): TD3's own clipped double-Q
learning and maximization of ``Q_1``, or OPOLO's dual forms. Like :class:`~rankgame.policy.sac.SAC` it
knows nothing about rankings: every update relabels its batches with ``reward_fn(reward_params,
batch)``, and :meth:`TD3.update` fuses a stack of gradient steps ``(n, batch_size, ...)`` with
``lax.scan``. The actor is updated, and the target networks averaged, every ``policy_delay``-th
critic step.

The actor network is SAC's :class:`~rankgame.policy.sac.Actor` head, of which TD3 uses the mean only:
a saved TD3 actor is read by ``rankgame evaluate`` like any SAC actor, whose deterministic action is
the same ``tanh(mean)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import flax.struct
import jax
import jax.numpy as jnp
import optax

from rankgame.absorbing import absorbing_value
from rankgame.errors import nonfinite_fields, require
from rankgame.policy.sac import Actor, Batch, RewardFn, TwinCritic, env_reward
from rankgame.policy.td3_objectives import ActorObjective, ClippedDoubleQ, CriticObjective, MaxFirstCritic


@dataclass(frozen=True)
class TD3Config:
    """Hyperparameters of TD3. Defaults are OPOLO's public settings (400-300 networks, batches of 100, a
    thousand gradient steps after every thousand environment steps, ten thousand random steps first)."""

    hidden_sizes: tuple[int, ...] = (400, 300)
    """Hidden layer widths of the actor and of each critic (ReLU)."""
    lr: float | None = None
    """Adam learning rate of the actor and the critics; default: the method's value for the task (opolo:
    1e-4 on Hopper, 3e-4 elsewhere), 3e-4 without one."""
    batch_size: int = 100
    """Transitions per gradient step."""
    gamma: float = 0.99
    """Discount factor."""
    polyak: float = 0.995
    """Target network averaging: target <- polyak * target + (1 - polyak) * online."""
    policy_delay: int = 2
    """Critic steps per actor step (and per target-network update)."""
    exploration_noise: float = 0.1
    """Standard deviation of the Gaussian noise added to the actor's actions when acting."""
    target_noise: float = 0.2
    """Standard deviation of the target policy smoothing noise of TD3's own critic objective (OPOLO's dual
    objective bootstraps the online actor's action without noise)."""
    target_noise_clip: float = 0.5
    """Bound on the absolute target policy smoothing noise."""
    start_steps: int = 10_000
    """Environment steps with uniformly random actions before the actor acts."""
    update_after: int = 10_000
    """Environment steps before the first gradient step."""
    update_every: int = 1000
    """Environment steps between update calls; each call fuses update_every gradient steps."""
    updates_per_step: float = 1.0
    """Gradient steps per environment step."""
    buffer_size: int = 1_000_000
    """Replay buffer capacity in transitions."""

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        require(
            [
                (not nonfinite_fields(self), f"{', '.join(nonfinite_fields(self))} must be finite"),
                (self.lr is None or self.lr > 0.0, "td3.lr must be positive"),
                (self.batch_size > 0, "td3.batch_size must be positive"),
                (0.0 <= self.gamma < 1.0, "td3.gamma must lie in [0, 1)"),
                (0.0 <= self.polyak < 1.0, "td3.polyak must lie in [0, 1)"),
                (self.policy_delay > 0, "td3.policy_delay must be positive"),
                (
                    min(self.exploration_noise, self.target_noise, self.target_noise_clip) >= 0.0,
                    "td3 noises must be >= 0",
                ),
                (
                    self.update_every > 0 and self.updates_per_step > 0.0,
                    "td3 update_every and updates_per_step must be positive",
                ),
                (self.buffer_size >= self.batch_size, "td3.buffer_size must be at least td3.batch_size"),
                (all(h > 0 for h in self.hidden_sizes), "td3.hidden_sizes must be positive"),
                (self.start_steps >= 0 and self.update_after >= 0, "td3 start_steps and update_after must be >= 0"),
            ]
        )

    def with_lr(self, default: float) -> TD3Config:
        """This config with ``lr`` set to ``default`` if it was left unset."""
        return self if self.lr is not None else replace(self, lr=default)


@flax.struct.dataclass
class TD3State:
    """Everything TD3 learns, as one pytree (saved, restored and carried through ``lax.scan``)."""

    actor_params: Any
    critic_params: Any
    target_actor_params: Any
    target_critic_params: Any
    actor_opt_state: Any
    critic_opt_state: Any
    key: jax.Array
    n_updates: jax.Array


@dataclass
class TD3:
    """TD3 for one observation/action size. Build once; :meth:`update` and :meth:`act` are jitted.

    Attributes:
        reward_fn: how each sampled batch is labelled with rewards (static).
        absorbing: the last observation entry is an absorbing flag (:mod:`rankgame.absorbing`): the
            critic objectives use the absorbing state's closed-form value ``r(s_abs) / (1 - gamma)`` for
            transitions into it, as SAC does.
        critic_objective, actor_objective: what the critics and the actor minimize
            (:mod:`rankgame.policy.td3_objectives`).
    """

    obs_dim: int
    act_dim: int
    config: TD3Config
    reward_fn: RewardFn = env_reward
    absorbing: bool = False
    critic_objective: CriticObjective = field(default_factory=ClippedDoubleQ)
    actor_objective: ActorObjective = field(default_factory=MaxFirstCritic)
    actor: Actor = field(init=False)
    critic: TwinCritic = field(init=False)

    def __post_init__(self) -> None:
        self.config.validate()
        require([(self.config.lr is not None, "TD3 needs a learning rate (td3.lr)")])
        self.actor = Actor(self.config.hidden_sizes, self.act_dim)
        self.critic = TwinCritic(self.config.hidden_sizes)
        self.actor_tx = optax.adam(self.config.lr)
        self.critic_tx = optax.adam(self.config.lr)
        self.update = jax.jit(self._update_many, donate_argnums=(0,))
        self.act = jax.jit(self._act)

    def init(self, key: jax.Array) -> TD3State:
        """Fresh parameters, equal target copies and optimizer states from a ``jax.random`` key."""
        k_actor, k_critic, k_state = jax.random.split(key, 3)
        obs = jnp.zeros((1, self.obs_dim), jnp.float32)
        actor_params = self.actor.init(k_actor, obs)
        critic_params = self.critic.init(k_critic, obs, jnp.zeros((1, self.act_dim), jnp.float32))
        return TD3State(
            actor_params=actor_params,
            critic_params=critic_params,
            target_actor_params=jax.tree.map(jnp.copy, actor_params),
            target_critic_params=jax.tree.map(jnp.copy, critic_params),
            actor_opt_state=self.actor_tx.init(actor_params),
            critic_opt_state=self.critic_tx.init(critic_params),
            key=k_state,
            n_updates=jnp.zeros((), jnp.int32),
        )

    def policy_action(self, actor_params: Any, obs: jax.Array) -> jax.Array:
        """The deterministic action ``tanh(mean)`` ``(B, act_dim)`` for ``obs (B, obs_dim)``."""
        mean, _ = self.actor.apply(actor_params, obs)
        return jnp.tanh(mean)

    def _act(self, actor_params: Any, obs: jax.Array, noise: jax.Array) -> jax.Array:
        """Exploring actions ``clip(pi(s) + exploration_noise * noise, -1, 1)`` ``(B, act_dim)`` for standard
        normal ``noise``; ``noise = 0`` gives the deterministic action."""
        acts = self.policy_action(actor_params, obs) + self.config.exploration_noise * noise
        return jnp.clip(acts, -1.0, 1.0)

    def absorbing_value(self, reward_params: Any) -> jax.Array:
        """Value ``()`` of the absorbing state, ``r(s_abs) / (1 - gamma)``: it loops on itself forever."""
        return absorbing_value(self.reward_fn, reward_params, self.obs_dim, self.act_dim, self.config.gamma)

    def losses(
        self, state: TD3State, batch: Batch, reward_params: Any
    ) -> tuple[TD3State, tuple[dict[str, jax.Array], dict[str, jax.Array], jax.Array]]:
        """One critic step on ``batch`` and, every ``policy_delay``-th step, one actor step and the target update.

        Returns the new state, the critic's metrics, the actor's metrics (zeros on a step without an
        actor step) and whether the actor stepped (``()``, 1.0 or 0.0).

        Batch keys: ``obs (B, obs_dim)``, ``acts (B, act_dim)`` normalized, ``next_obs (B, obs_dim)``,
        ``dones (B,)``, plus whatever ``reward_fn`` and the objectives read.
        """
        cfg = self.config
        key, k_critic = jax.random.split(state.key)
        prepared = self.critic_objective.prepare(self, state, batch, reward_params, k_critic)

        def critic_loss_fn(critic_params: Any) -> tuple[jax.Array, tuple[jax.Array, dict[str, jax.Array]]]:
            return self.critic_objective.loss(self, critic_params, state.actor_params, batch, prepared)

        (critic_loss, (q, critic_metrics)), grads = jax.value_and_grad(critic_loss_fn, has_aux=True)(
            state.critic_params
        )
        updates, critic_opt_state = self.critic_tx.update(grads, state.critic_opt_state)
        critic_params = optax.apply_updates(state.critic_params, updates)

        def actor_loss_fn(actor_params: Any) -> tuple[jax.Array, dict[str, jax.Array]]:
            return self.actor_objective.loss(self, actor_params, critic_params, batch)

        def actor_step(_: None) -> tuple[Any, Any, Any, Any, jax.Array, dict[str, jax.Array]]:
            (actor_loss, actor_metrics), grads = jax.value_and_grad(actor_loss_fn, has_aux=True)(state.actor_params)
            updates, actor_opt_state = self.actor_tx.update(grads, state.actor_opt_state)
            actor_params = optax.apply_updates(state.actor_params, updates)
            rate = 1.0 - cfg.polyak
            target_actor = optax.incremental_update(actor_params, state.target_actor_params, rate)
            target_critic = optax.incremental_update(critic_params, state.target_critic_params, rate)
            return actor_params, actor_opt_state, target_actor, target_critic, actor_loss, actor_metrics

        def no_actor_step(_: None) -> tuple[Any, Any, Any, Any, jax.Array, dict[str, jax.Array]]:
            shapes = jax.eval_shape(actor_loss_fn, state.actor_params)
            loss, metrics = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
            held = (state.actor_params, state.actor_opt_state, state.target_actor_params, state.target_critic_params)
            return (*held, loss, metrics)

        due = (state.n_updates + 1) % cfg.policy_delay == 0
        actor_params, actor_opt_state, target_actor, target_critic, actor_loss, actor_metrics = jax.lax.cond(
            due, actor_step, no_actor_step, None
        )
        new_state = TD3State(
            actor_params=actor_params,
            critic_params=critic_params,
            target_actor_params=target_actor,
            target_critic_params=target_critic,
            actor_opt_state=actor_opt_state,
            critic_opt_state=critic_opt_state,
            key=key,
            n_updates=state.n_updates + 1,
        )
        critic_metrics = {"losses/critic": critic_loss, "losses/q": jnp.mean(q), **critic_metrics}
        actor_metrics = {"losses/actor": actor_loss, **actor_metrics}
        return new_state, (critic_metrics, actor_metrics, due.astype(jnp.float32))

    def _update_many(
        self, state: TD3State, batches: Batch, reward_params: Any
    ) -> tuple[TD3State, dict[str, jax.Array]]:
        """``n`` fused gradient steps over ``batches`` ``(n, batch_size, ...)``; metrics averaged over the steps
        that computed them (the actor's over its own steps)."""

        def step(carry: TD3State, batch: Batch) -> tuple[TD3State, Any]:
            return self.losses(carry, batch, reward_params)

        state, (critic_metrics, actor_metrics, stepped) = jax.lax.scan(step, state, batches)
        n_actor = jnp.sum(stepped)
        actor_means = {
            name: jnp.sum(values * stepped) / jnp.maximum(n_actor, 1.0) for name, values in actor_metrics.items()
        }
        return state, {**jax.tree.map(jnp.mean, critic_metrics), **actor_means, "losses/actor_steps": n_actor}
