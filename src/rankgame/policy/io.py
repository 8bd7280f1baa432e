"""Saving and loading a trained SAC policy (the actor) with what is needed to run it again."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import flax.serialization
import jax
import numpy as np

from rankgame.atomic import atomic_write_bytes
from rankgame.checkpoint import flatten_tree, require_finite
from rankgame.envs.rollout import PolicyFn
from rankgame.policy.learner import make_policy_fn
from rankgame.policy.sac import SAC, SACConfig
from rankgame.serialized import read_header_file

POLICY_FORMAT = "rankgame-policy"
POLICY_VERSION = 1


@dataclass
class SavedPolicy:
    """A policy read back from disk: its environment, SAC config and actor parameters."""

    env_id: str
    sac: SAC
    actor_params: Any
    act_low: np.ndarray
    act_high: np.ndarray
    metadata: dict[str, Any]

    def policy_fn(self, deterministic: bool = True, seed: int = 0) -> PolicyFn:
        """The policy as ``obs -> action`` in environment units."""
        rng = np.random.default_rng(seed)
        absorbing = bool(self.metadata.get("absorbing_flag"))  # trained by the ranking game
        return make_policy_fn(self.sac, self.actor_params, self.act_low, self.act_high, rng, deterministic, absorbing)


def save_policy(
    path: str | Path,
    sac: SAC,
    actor_params: Any,
    env_id: str,
    act_low: np.ndarray,
    act_high: np.ndarray,
    **metadata: Any,
) -> Path:
    """Write the actor of ``sac`` to ``path`` (msgpack), atomically; a non-finite parameter raises
    :class:`~rankgame.errors.NonFiniteError` and nothing is written."""
    require_finite(flatten_tree("actor_params", actor_params))
    header = {
        "format": POLICY_FORMAT,
        "version": POLICY_VERSION,
        "env_id": env_id,
        "obs_dim": sac.obs_dim,
        "act_dim": sac.act_dim,
        "sac_config": dataclasses.asdict(sac.config),
        "metadata": metadata,
    }
    payload = {
        "header": json.dumps(header),
        "act_low": np.asarray(act_low, np.float32),
        "act_high": np.asarray(act_high, np.float32),
        "actor_params": flax.serialization.to_state_dict(actor_params),
    }
    return atomic_write_bytes(path, flax.serialization.msgpack_serialize(payload))


def load_policy(path: str | Path) -> SavedPolicy:
    """Read a policy written by :func:`save_policy`; a one-line :class:`RankGameError` if it is not one."""
    payload, header = read_header_file(path, "policy", POLICY_FORMAT, POLICY_VERSION)
    config_fields = dict(header["sac_config"])
    config_fields["hidden_sizes"] = tuple(config_fields["hidden_sizes"])
    # Files written while SAC had a choice of initializers name it; a trained actor does not depend on it.
    config_fields.pop("weight_init", None)
    sac = SAC(header["obs_dim"], header["act_dim"], SACConfig(**config_fields))
    template = sac.init(jax.random.key(0)).actor_params
    actor_params = flax.serialization.from_state_dict(template, payload["actor_params"])
    return SavedPolicy(
        env_id=header["env_id"],
        sac=sac,
        actor_params=actor_params,
        act_low=np.asarray(payload["act_low"]),
        act_high=np.asarray(payload["act_high"]),
        metadata=header["metadata"],
    )
