"""The learned reward of a run as a file, and that file as a plain function of observations.

``export_reward(RUN, FILE)`` (``rankgame export-reward RUN --out FILE``) takes the reward player's
parameters from a run's checkpoint; ``load_reward(FILE)`` returns a :class:`LearnedReward`, a callable
``reward(obs, acts=None, next_obs=None) -> (N,)`` in the task's own units, usable without the run or
the rest of rankgame's training code. File: msgpack with a JSON ``header`` (the format, the task, the
reward's input kind, sizes, action bounds, network shape, bound) and the ``params`` tree.
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
    prefix = "reward/params/"
    params = {name[len(prefix) :]: array for name, array in arrays.items() if name.startswith(prefix)}
    require_finite(params)
    header = {"format": REWARD_FORMAT, "version": REWARD_VERSION, "env_steps": metadata["env_steps"], **spec}
    payload = {"header": json.dumps(header), "params": _nest(params)}
    return atomic_write_bytes(path, flax.serialization.msgpack_serialize(payload))


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
        input: what it reads: ``s`` (observations), ``ss`` (observations and next observations) or
            ``sa`` (observations and actions).
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
            acts: ``(N, act_dim)`` actions in the task's units, for an ``sa`` reward.
            next_obs: ``(N, obs_dim)`` next observations, for an ``ss`` reward.
        """
        h = self.header
        obs = _rows(obs, h["obs_dim"], "obs")
        batch = {"obs": flag_obs(obs)}
        if self.input == "sa":
            if acts is None:
                raise RankGameError("this reward reads (s, a): pass acts")
            acts = _rows(acts, h["act_dim"], "acts")
            low, high = np.asarray(h["act_low"], np.float32), np.asarray(h["act_high"], np.float32)
            batch["acts"] = 2.0 * (acts - low) / (high - low) - 1.0
        if self.input == "ss":
            if next_obs is None:
                raise RankGameError("this reward reads (s, s'): pass next_obs")
            batch["next_obs"] = flag_obs(_rows(next_obs, h["obs_dim"], "next_obs"))
        if len({len(x) for x in batch.values()}) != 1:
            raise RankGameError("obs, acts and next_obs must have the same number of rows")
        return np.asarray(self.apply(self.params, {k: jnp.asarray(v) for k, v in batch.items()}))


def _rows(x: np.ndarray, dim: int, name: str) -> np.ndarray:
    x = np.asarray(x, np.float32)
    x = x[None] if x.ndim == 1 else x
    if x.ndim != 2 or x.shape[1] != dim:
        raise RankGameError(f"{name} must have shape (N, {dim}), got {x.shape}")
    return x


def _reward_function(header: dict[str, Any]) -> Callable[[Any, dict[str, jax.Array]], jax.Array]:
    """The jitted bounded reward ``(params, batch) -> (N,)`` of the network the header describes."""
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
