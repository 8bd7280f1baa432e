"""The learned reward of a run as a file, and that file as a plain function of observations.

``export_reward(RUN, FILE)`` (``rankgame export-reward RUN --out FILE``) takes the reward player's
parameters from a run's checkpoint; ``load_reward(FILE)`` returns a :class:`LearnedReward`, a callable
``reward(obs, acts=None, next_obs=None) -> (N,)`` in the task's own units, usable without the run or
the rest of rankgame's training code. File: msgpack with a JSON ``header`` (the format, the task, the
reward's input kind, sizes, action bounds, network shape, bound) and the ``params`` tree.

Two kinds of reward are exported: a reward player's network (``kind: network``, every game method),
and the reward that IQ-Learn's critic implies (``kind: soft-q``), ``r(s, a, s') = min_i Q_i(s, a) -
gamma V(s')`` with ``V(s') = E_{a' ~ pi}[min_i Q_i(s', a') - alpha log pi(a'|s')]`` averaged over
:data:`VALUE_SAMPLES` fixed draws of ``a'`` (the reward of a non-terminal transition; a terminal one's is
``min_i Q_i(s, a)``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import flax.serialization
import jax
import jax.numpy as jnp
import numpy as np

from rankgame.absorbing import flag_obs
from rankgame.atomic import atomic_write_bytes
from rankgame.checkpoint import CHECKPOINT_NAME, load_checkpoint, require_finite
from rankgame.errors import RankGameError
from rankgame.reward.inputs import InputLayout
from rankgame.reward.losses import bound_reward
from rankgame.reward.nets import RewardNet
from rankgame.serialized import read_header_file

REWARD_FORMAT = "rankgame-reward"
REWARD_VERSION = 1

#: Policy actions drawn (with a fixed key) to estimate the soft value ``V(s')`` of a soft-Q reward.
VALUE_SAMPLES = 32


def export_reward(run: str | Path, path: str | Path) -> Path:
    """Write the learned reward in the checkpoint of the ``rankgame train`` run in folder ``run`` to ``path``."""
    run = Path(run)
    ckpt = run / CHECKPOINT_NAME
    if not ckpt.is_file():
        raise RankGameError(f"no {CHECKPOINT_NAME} in {run}: pass the folder of a rankgame train run")
    metadata, arrays = load_checkpoint(ckpt)
    if "reward_spec" not in metadata:
        raise RankGameError(f"{ckpt} holds no learned reward (is it a rankgame expert run?)")
    spec = metadata["reward_spec"]
    prefixes = SOFT_Q_PARAMS if spec.get("kind") == "soft-q" else {"": "reward/params/"}
    params: dict[str, Any] = {}
    for key, prefix in prefixes.items():
        part = {name[len(prefix) :]: array for name, array in arrays.items() if name.startswith(prefix)}
        require_finite(part)
        params.update({f"{key}/{name}" if key else name: array for name, array in part.items()})
    header = {"format": REWARD_FORMAT, "version": REWARD_VERSION, "env_steps": metadata["env_steps"], **spec}
    payload = {"header": json.dumps(header), "params": _nest(params)}
    return atomic_write_bytes(path, flax.serialization.msgpack_serialize(payload))


#: Where a soft-Q reward's networks are in a checkpoint: SAC's critic and actor.
SOFT_Q_PARAMS = {"critic": "sac/critic_params/", "actor": "sac/actor_params/"}


def _nest(flat: dict[str, np.ndarray]) -> dict[str, Any]:
    """``{"params/MLP_0/Dense_0/kernel": x}`` -> ``{"params": {"MLP_0": {"Dense_0": {"kernel": x}}}}``."""
    tree: dict[str, Any] = {}
    for name, array in flat.items():
        *parents, leaf = name.split("/")
        node = tree
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = array
    return tree


@dataclass(frozen=True)
class LearnedReward:
    """A learned reward: ``reward(obs, acts=None, next_obs=None) -> rewards (N,)``.

    Attributes:
        env_id: the task it was learned on.
        input: what it reads: ``s`` (observations), ``ss`` (observations and next observations),
            ``sa`` (observations and actions) or ``sas`` (all three: a soft-Q reward).
        header: everything the file records about it (sizes, bounds, the step it was taken at).
    """

    env_id: str
    input: str
    header: dict[str, Any]
    params: Any
    apply: Callable[[Any, dict[str, jax.Array]], jax.Array]

    def __call__(
        self, obs: np.ndarray, acts: np.ndarray | None = None, next_obs: np.ndarray | None = None
    ) -> np.ndarray:
        """Bounded rewards ``(N,)`` of real (non-absorbing) states.

        Args:
            obs: ``(N, obs_dim)`` observations (or one ``(obs_dim,)``).
            acts: ``(N, act_dim)`` actions in the task's units, for an ``sa`` or ``sas`` reward.
            next_obs: ``(N, obs_dim)`` next observations, for an ``ss`` or ``sas`` reward.
        """
        h = self.header
        flag = flag_obs if h.get("absorbing", True) else np.asarray
        obs = _rows(obs, h["obs_dim"], "obs")
        batch = {"obs": flag(obs)}
        if self.input in ("sa", "sas"):
            if acts is None:
                raise RankGameError("this reward reads (s, a): pass acts")
            acts = _rows(acts, h["act_dim"], "acts")
            low, high = np.asarray(h["act_low"], np.float32), np.asarray(h["act_high"], np.float32)
            batch["acts"] = 2.0 * (acts - low) / (high - low) - 1.0
        if self.input in ("ss", "sas"):
            if next_obs is None:
                raise RankGameError("this reward reads s': pass next_obs")
            batch["next_obs"] = flag(_rows(next_obs, h["obs_dim"], "next_obs"))
        if len({len(x) for x in batch.values()}) != 1:
            raise RankGameError("obs, acts and next_obs must have the same number of rows")
        return np.asarray(self.apply(self.params, {k: jnp.asarray(v) for k, v in batch.items()}))


def _rows(x: np.ndarray, dim: int, name: str) -> np.ndarray:
    x = np.asarray(x, np.float32)
    x = x[None] if x.ndim == 1 else x
    if x.ndim != 2 or x.shape[1] != dim:
        raise RankGameError(f"{name} must have shape (N, {dim}), got {x.shape}")
    return x


def _soft_q_reward(header: dict[str, Any]) -> Callable[[Any, dict[str, jax.Array]], jax.Array]:
    """The jitted reward ``(params, batch) -> (N,)`` that the critic and actor in ``params`` imply."""
    from rankgame.policy.critic_objectives import sampled_value
    from rankgame.policy.sac import SAC, SACConfig

    config = SACConfig(hidden_sizes=tuple(header["hidden_sizes"]), gamma=header["gamma"])
    sac = SAC(header["obs_dim"], header["act_dim"], config)
    alpha, gamma = jnp.asarray(header["alpha"], jnp.float32), header["gamma"]

    def reward(params: Any, batch: dict[str, jax.Array]) -> jax.Array:
        n = batch["obs"].shape[0]
        noise = jax.random.normal(jax.random.key(0), (VALUE_SAMPLES, n, header["act_dim"]))
        values = jax.vmap(lambda z: sampled_value(sac, params["critic"], params["actor"], batch["next_obs"], z, alpha))(
            noise
        )
        q = jnp.min(sac.critic.apply(params["critic"], batch["obs"], batch["acts"]), axis=0)
        return q - gamma * jnp.mean(values, axis=0)

    return jax.jit(reward)


def _reward_function(header: dict[str, Any]) -> Callable[[Any, dict[str, jax.Array]], jax.Array]:
    """The jitted bounded reward ``(params, batch) -> (N,)`` of the network the header describes."""
    if header.get("kind") == "soft-q":
        return _soft_q_reward(header)
    layout = InputLayout(header["obs_dim"], header["act_dim"], header["input"])
    columns = None if header["columns"] is None else tuple(header["columns"])
    net = RewardNet(tuple(header["hidden_sizes"]), columns, header["spectral_norm"])
    r_max, bound = header["r_max"], header["bound"]
    return jax.jit(lambda params, batch: bound_reward(net.apply(params, layout.from_batch(batch)), r_max, bound))


def load_reward(path: str | Path) -> LearnedReward:
    """Read a reward written by :func:`export_reward`; a one-line :class:`RankGameError` if it is not one."""
    payload, header = read_header_file(path, "reward", REWARD_FORMAT, REWARD_VERSION)
    try:
        return LearnedReward(header["env_id"], header["input"], header, payload["params"], _reward_function(header))
    except (KeyError, TypeError, ValueError) as exc:
        raise RankGameError(f"{path}: incomplete reward file header ({exc})") from None
