"""Proximal Policy Optimization (Schulman et al., 2017) as pure, jitted JAX functions.

The on-policy policy player of adversarial imitation (GAIL, GAIfO). Like SAC
(:mod:`rankgame.policy.sac`) it knows nothing about the reward it maximizes: :meth:`PPO.update`
relabels the whole rollout with an injected ``reward_fn(reward_params, batch) -> rews (T,)`` before
computing advantages, so a learned reward that moved while the rollout was collected is never stale.
This module owns the config, the value network, GAE, the clipped surrogate and the fused update;
:mod:`rankgame.policy.ppo_learner` drives it in an environment.

One update is a single XLA call: the rewards, the values and GAE (a reverse ``lax.scan``), then
``epochs`` passes over the rollout, each shuffled with a ``jax.random`` key and cut into
``rollout_steps / minibatch_size`` minibatches, fused with two nested ``lax.scan``.

The actor is SAC's :class:`~rankgame.policy.sac.Actor` (a tanh-squashed Gaussian with a
state-dependent log-std, ReLU hidden layers), so that a PPO actor is saved and loaded as a SAC actor
by :mod:`rankgame.policy.io` and runs in ``rankgame evaluate`` unchanged. The pre-tanh sample ``u`` is
stored when acting, so the probability ratio never needs ``atanh``; the tanh Jacobian is the same
for the old and the new policy and cancels in the ratio. The entropy (the bonus and the logged
``losses/entropy``) is the closed-form entropy of the pre-tanh Gaussian, as CleanRL's
``Normal(...).entropy()``; the squashed distribution has none in closed form. The value network is a
separate ReLU MLP with the same hidden sizes; one Adam optimizer updates both networks with the
combined loss ``actor - entropy_coef * entropy + value_coef * critic`` after clipping the joint
gradient norm, as CleanRL does.

Where the defaults of :class:`PPOConfig` come from:

* Schulman et al. (2017), Table 3 (MuJoCo): horizon ``rollout_steps = 2048``, Adam stepsize
  ``lr = 3e-4``, ``epochs = 10``, ``minibatch_size = 64``, ``gamma = 0.99``, ``gae_lambda = 0.95``;
  Section 6.1: ``clip = 0.2``; no entropy bonus on MuJoCo (``entropy_coef = 0``); two hidden layers
  of 64 units.
* CleanRL's ``ppo_continuous_action.py`` defaults (which agree with all of the above): ``value_coef
  = 0.5``, ``max_grad_norm = 0.5``, ``normalize_advantages`` (per minibatch), Adam ``eps = 1e-5``.

Deliberate differences from both: ReLU instead of tanh hidden layers, a state-dependent log-std and
tanh squashing (the SAC actor, see above), Flax's default initializers instead of orthogonal ones
(but the actor's output layer scaled by ``actor_output_scale = 0.01``, CleanRL's std of its mean
head, so the first policy is nearly ``tanh(N(0, 1))`` everywhere and does not drift to one side),
an unclipped value loss (the paper's squared error; CleanRL clips it by default), a constant
learning rate (CleanRL anneals it to 0 over a run whose length the learner does not know), and no
observation or reward normalization (CleanRL's wrappers): a learned reward is bounded already, and
a running observation normalizer would have to travel with every saved policy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import flax.linen as nn
import flax.struct
import jax
import jax.numpy as jnp
import optax

from rankgame.absorbing import absorbing_value
from rankgame.errors import nonfinite_fields, require
from rankgame.nets import MLP
from rankgame.policy.sac import Actor, Batch, RewardFn, env_reward, squashed_gaussian_sample


@dataclass(frozen=True)
class PPOConfig:
    """Hyperparameters of PPO. Defaults: Schulman et al. (2017)'s MuJoCo settings and CleanRL's
    ``ppo_continuous_action`` (see :mod:`rankgame.policy.ppo`)."""

    hidden_sizes: tuple[int, ...] = (64, 64)
    """Hidden layer widths of the actor and of the value network (ReLU: the actor is SAC's, so a PPO
    policy saves and loads as a SAC policy)."""
    lr: float = 3e-4
    """Adam learning rate of the actor and the value network (constant)."""
    adam_eps: float = 1e-5
    """Adam's epsilon (CleanRL's; Adam's own default is 1e-8)."""
    rollout_steps: int = 2048
    """Environment steps collected per update (the horizon T of the paper)."""
    epochs: int = 10
    """Passes over each rollout per update, each in a new random order."""
    minibatch_size: int = 64
    """Transitions per gradient step; must divide rollout_steps."""
    gamma: float = 0.99
    """Discount factor."""
    gae_lambda: float = 0.95
    """GAE's lambda: 0 is the one-step TD error, 1 the Monte Carlo return minus the value."""
    clip: float = 0.2
    """Clipping range epsilon of the probability ratio in the surrogate objective."""
    entropy_coef: float = 0.0
    """Weight of the entropy bonus (of the pre-tanh Gaussian)."""
    value_coef: float = 0.5
    """Weight of the value loss in the combined loss."""
    max_grad_norm: float = 0.5
    """Global norm the joint gradient of both networks is clipped to."""
    normalize_advantages: bool = True
    """Standardize the advantages within each minibatch."""
    actor_output_scale: float = 0.01
    """Factor on the initial weights of the actor's output layer, so that the first policy is nearly
    tanh(N(0, 1)) in every state (CleanRL initializes its mean head with std 0.01)."""

    @property
    def n_minibatches(self) -> int:
        """Gradient steps per epoch, ``rollout_steps / minibatch_size``."""
        return self.rollout_steps // self.minibatch_size

    def validate(self) -> None:
        """Raise ``ValueError`` with a one-line reason if the values make no sense together."""
        checks = [
            (not nonfinite_fields(self), f"{', '.join(nonfinite_fields(self))} must be finite"),
            (self.rollout_steps > 0 and self.minibatch_size > 0, "rollout_steps and minibatch_size must be positive"),
            (self.rollout_steps % self.minibatch_size == 0, "minibatch_size must divide rollout_steps"),
            (self.epochs > 0, "epochs must be positive"),
            (0.0 <= self.gamma < 1.0, "gamma must lie in [0, 1)"),
            (0.0 <= self.gae_lambda <= 1.0, "gae_lambda must lie in [0, 1]"),
            (self.clip > 0.0, "clip must be positive"),
            (self.lr > 0.0 and self.adam_eps > 0.0, "lr and adam_eps must be positive"),
            (self.entropy_coef >= 0.0 and self.value_coef > 0.0, "entropy_coef must be >= 0 and value_coef > 0"),
            (self.max_grad_norm > 0.0, "max_grad_norm must be positive"),
            (self.actor_output_scale > 0.0, "actor_output_scale must be positive"),
            (all(h > 0 for h in self.hidden_sizes), "hidden_sizes must be positive"),
        ]
        require(checks)


class ValueNet(nn.Module):
    """State-value network ``obs (B, obs_dim) -> V (B,)`` (ReLU MLP with a linear output)."""

    hidden_sizes: tuple[int, ...]

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        return MLP(self.hidden_sizes, 1)(obs)[..., 0]


def gae(
    rews: jax.Array, values: jax.Array, next_values: jax.Array, ends: jax.Array, gamma: float, lam: float
) -> jax.Array:
    """Generalized advantage estimates (Schulman et al., 2016) of one rollout, by a reverse ``lax.scan``.

    Args:
        rews: ``(T,)`` rewards ``r_t``.
        values: ``(T,)`` ``V(s_t)``.
        next_values: ``(T,)`` the value of what follows step ``t``: ``V(s_{t+1})``, or what replaces
            it after a termination (0, or the absorbing state's value).
        ends: ``(T,)`` 1.0 where an episode ends after step ``t`` (a termination, a time limit or a
            cut), else 0.0. The rollout's last step always ends the recursion.
        gamma, lam: discount and GAE's lambda.
    Returns:
        ``(T,)`` ``A_t = delta_t + gamma lam (1 - ends_t) A_{t+1}`` with ``A_T = 0`` and
        ``delta_t = r_t + gamma next_values_t - values_t``.
    """
    deltas = rews + gamma * next_values - values

    def step(next_adv: jax.Array, inputs: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        delta, end = inputs
        adv = delta + gamma * lam * (1.0 - end) * next_adv
        return adv, adv

    _, advantages = jax.lax.scan(step, jnp.zeros((), deltas.dtype), (deltas, ends), reverse=True)
    return advantages


def clipped_surrogate(logp: jax.Array, old_logp: jax.Array, advantages: jax.Array, clip: float) -> jax.Array:
    """PPO's clipped surrogate loss ``()`` (to minimize), all inputs ``(B,)``:
    ``-mean(min(rho A, clip(rho, 1 - clip, 1 + clip) A))`` with ``rho = exp(logp - old_logp)``."""
    ratio = jnp.exp(logp - old_logp)
    clipped = jnp.clip(ratio, 1.0 - clip, 1.0 + clip)
    return -jnp.mean(jnp.minimum(ratio * advantages, clipped * advantages))


def squashed_gaussian_logp(mean: jax.Array, log_std: jax.Array, pre_tanh: jax.Array) -> jax.Array:
    """Log-probability ``(B,)`` of the tanh-squashed Gaussian at ``tanh(pre_tanh)``; inputs ``(B, act_dim)``.

    The same quantity :func:`~rankgame.policy.sac.squashed_gaussian_sample` returns for the noise that
    produced ``pre_tanh``, so no ``atanh`` of a saturated action is ever taken."""
    noise = (pre_tanh - mean) / jnp.exp(log_std)
    return squashed_gaussian_sample(mean, log_std, noise)[1]


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    """Entropy ``(B,)`` of the diagonal Gaussian with ``log_std (B, act_dim)`` (before the tanh)."""
    return jnp.sum(log_std + 0.5 * jnp.log(2.0 * jnp.pi * jnp.e), axis=-1)


def scale_output_layer(actor_params: Any, scale: float) -> Any:
    """``actor_params`` with the kernel of the actor's output layer (the last ``Dense`` of its MLP, which
    gives the mean and the log-std) multiplied by ``scale``; the tree and its shapes are unchanged."""
    layers = actor_params["params"]["MLP_0"]
    last = max(layers, key=lambda name: int(name.split("_")[-1]))
    scaled = {**layers[last], "kernel": layers[last]["kernel"] * scale}
    return {**actor_params, "params": {**actor_params["params"], "MLP_0": {**layers, last: scaled}}}


@flax.struct.dataclass
class PPOState:
    """Everything PPO learns, as one pytree (saved, restored and carried through ``lax.scan``).

    ``actor_params`` has exactly the tree of a SAC actor with the same hidden sizes."""

    actor_params: Any
    critic_params: Any
    opt_state: Any
    key: jax.Array
    n_updates: jax.Array


@dataclass
class PPO:
    """PPO for one observation/action size. Build once; :meth:`update` and :meth:`act` are jitted.

    A rollout (what :meth:`update` takes) is a dict of arrays with ``T = rollout_steps`` rows:
    ``obs (T, obs_dim)``, ``acts (T, act_dim)`` in ``(-1, 1)``, ``pre_tanh (T, act_dim)`` (``acts =
    tanh(pre_tanh)``), ``logp (T,)`` the acting policy's log-probability of ``acts``, ``next_obs
    (T, obs_dim)``, ``dones (T,)`` 1.0 at a true termination, ``truncs (T,)`` 1.0 where the episode
    ended otherwise (a time limit, or an episode cut by the learner), ``rews (T,)`` the environment's
    reward. Step ``t + 1`` continues step ``t`` unless ``dones_t`` or ``truncs_t``.

    Attributes:
        reward_fn: relabels the rollout, ``reward_fn(reward_params, batch) -> (T,)`` with ``batch``
            the keys ``obs``, ``acts``, ``next_obs``, ``dones`` and ``rews`` (static: changing it
            recompiles).
        absorbing: observations carry the absorbing flag last (:mod:`rankgame.absorbing`) and a
            terminal step is stored as ``s -> s_abs``; the value after it is the absorbing state's
            exact value ``r(s_abs) / (1 - gamma)`` with the current reward (see
            :meth:`absorbing_value`) instead of 0. The self-loop is never stored: no action is taken
            in ``s_abs``.
    """

    obs_dim: int
    act_dim: int
    config: PPOConfig
    reward_fn: RewardFn = env_reward
    absorbing: bool = False
    actor: Actor = field(init=False)
    critic: ValueNet = field(init=False)

    def __post_init__(self) -> None:
        self.config.validate()
        cfg = self.config
        self.actor = Actor(cfg.hidden_sizes, self.act_dim)
        self.critic = ValueNet(cfg.hidden_sizes)
        self.tx = optax.chain(optax.clip_by_global_norm(cfg.max_grad_norm), optax.adam(cfg.lr, eps=cfg.adam_eps))
        self.update = jax.jit(self._update)
        self.act = jax.jit(self._act)

    def init(self, key: jax.Array) -> PPOState:
        """Fresh parameters and optimizer state from a ``jax.random`` key."""
        k_actor, k_critic, k_state = jax.random.split(key, 3)
        obs = jnp.zeros((1, self.obs_dim), jnp.float32)
        actor_params = scale_output_layer(self.actor.init(k_actor, obs), self.config.actor_output_scale)
        critic_params = self.critic.init(k_critic, obs)
        return PPOState(
            actor_params=actor_params,
            critic_params=critic_params,
            opt_state=self.tx.init((actor_params, critic_params)),
            key=k_state,
            n_updates=jnp.zeros((), jnp.int32),
        )

    def _act(self, actor_params: Any, obs: jax.Array, noise: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        """Sample for ``obs (B, obs_dim)`` with standard normal ``noise (B, act_dim)``: ``acts (B, act_dim)``
        in ``(-1, 1)``, ``pre_tanh (B, act_dim)`` and ``logp (B,)``. ``noise = 0`` gives the mean action."""
        mean, log_std = self.actor.apply(actor_params, obs)
        acts, logp = squashed_gaussian_sample(mean, log_std, noise)
        return acts, mean + jnp.exp(log_std) * noise, logp

    def absorbing_value(self, reward_params: Any) -> jax.Array:
        """Value ``()`` of the absorbing state, ``r(s_abs) / (1 - gamma)``: it loops on itself forever."""
        return absorbing_value(self.reward_fn, reward_params, self.obs_dim, self.act_dim, self.config.gamma)

    def gae_inputs(self, state: PPOState, rollout: Batch, reward_params: Any) -> dict[str, jax.Array]:
        """What GAE reads, each ``(T,)``: ``rews`` (relabelled by ``reward_fn``), ``values`` ``V(obs)``,
        ``next_values`` and ``ends`` (see :func:`gae`).

        ``next_values`` is ``V(next_obs)`` (after a time limit or a cut too), except after a true
        termination: 0, or with ``absorbing`` the absorbing state's value."""
        batch = {name: rollout[name] for name in ("obs", "acts", "next_obs", "dones", "rews")}
        rews = self.reward_fn(reward_params, batch)
        values = self.critic.apply(state.critic_params, rollout["obs"])
        next_values = self.critic.apply(state.critic_params, rollout["next_obs"])
        after_end = self.absorbing_value(reward_params) if self.absorbing else jnp.zeros_like(next_values)
        next_values = jnp.where(rollout["dones"] > 0.5, after_end, next_values)
        ends = jnp.maximum(rollout["dones"], rollout["truncs"])
        return {"rews": rews, "values": values, "next_values": next_values, "ends": ends}

    def losses(self, params: tuple[Any, Any], minibatch: Batch) -> tuple[jax.Array, dict[str, jax.Array]]:
        """Combined loss ``()`` of ``(actor_params, critic_params)`` on a minibatch, and its metrics.

        Minibatch keys, leading size ``B``: ``obs (B, obs_dim)``, ``pre_tanh (B, act_dim)``, ``logp (B,)``
        of the acting policy, ``advantages (B,)`` and ``returns (B,)`` (the value targets)."""
        cfg = self.config
        actor_params, critic_params = params
        mean, log_std = self.actor.apply(actor_params, minibatch["obs"])
        logp = squashed_gaussian_logp(mean, log_std, minibatch["pre_tanh"])
        advantages = minibatch["advantages"]
        if cfg.normalize_advantages:
            advantages = (advantages - jnp.mean(advantages)) / (jnp.std(advantages) + 1e-8)
        actor_loss = clipped_surrogate(logp, minibatch["logp"], advantages, cfg.clip)
        values = self.critic.apply(critic_params, minibatch["obs"])
        critic_loss = 0.5 * jnp.mean((values - minibatch["returns"]) ** 2)
        entropy = jnp.mean(gaussian_entropy(log_std))
        loss = actor_loss - cfg.entropy_coef * entropy + cfg.value_coef * critic_loss
        log_ratio = jax.lax.stop_gradient(logp - minibatch["logp"])
        ratio = jnp.exp(log_ratio)
        metrics = {
            "losses/actor": actor_loss,
            "losses/critic": critic_loss,
            "losses/entropy": entropy,
            "losses/approx_kl": jnp.mean((ratio - 1.0) - log_ratio),  # Schulman's low-variance estimator
            "losses/clip_fraction": jnp.mean((jnp.abs(ratio - 1.0) > cfg.clip).astype(jnp.float32)),
        }
        return loss, metrics

    def _update(self, state: PPOState, rollout: Batch, reward_params: Any) -> tuple[PPOState, dict[str, jax.Array]]:
        """One PPO update on a full rollout (see the class docstring); metrics averaged over its gradient steps."""
        cfg = self.config
        inputs = self.gae_inputs(state, rollout, reward_params)
        advantages = gae(
            inputs["rews"], inputs["values"], inputs["next_values"], inputs["ends"], cfg.gamma, cfg.gae_lambda
        )
        data = {
            "obs": rollout["obs"],
            "pre_tanh": rollout["pre_tanh"],
            "logp": rollout["logp"],
            "advantages": advantages,
            "returns": advantages + inputs["values"],
        }
        grad_fn = jax.value_and_grad(self.losses, has_aux=True)

        def minibatch_step(carry: tuple[Any, Any], idx: jax.Array) -> tuple[tuple[Any, Any], dict[str, jax.Array]]:
            params, opt_state = carry
            (_, metrics), grads = grad_fn(params, jax.tree.map(lambda x: x[idx], data))
            updates, opt_state = self.tx.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), metrics

        def epoch(
            carry: tuple[Any, Any, jax.Array], _: None
        ) -> tuple[tuple[Any, Any, jax.Array], dict[str, jax.Array]]:
            params, opt_state, key = carry
            key, k_perm = jax.random.split(key)
            order = jax.random.permutation(k_perm, cfg.rollout_steps).reshape(cfg.n_minibatches, cfg.minibatch_size)
            (params, opt_state), metrics = jax.lax.scan(minibatch_step, (params, opt_state), order)
            return (params, opt_state, key), metrics

        params = (state.actor_params, state.critic_params)
        (params, opt_state, key), metrics = jax.lax.scan(
            epoch, (params, state.opt_state, state.key), None, length=cfg.epochs
        )
        new_state = PPOState(
            actor_params=params[0],
            critic_params=params[1],
            opt_state=opt_state,
            key=key,
            n_updates=state.n_updates + 1,
        )
        metrics = jax.tree.map(jnp.mean, metrics)
        metrics["losses/reward"] = jnp.mean(inputs["rews"])
        return new_state, metrics
