"""Offline ranked trajectories for the (pref) methods (Sec. 4.2 and App. B.1, "offline annotated rankings").

The paper draws ``p = 10`` trajectories uniformly from the replay buffer of a SAC run trained on the
true reward and ranks them by their true return. :func:`sample_preferences` does exactly that with
the checkpoint of a ``rankgame expert`` run, whose replay buffer holds every transition of the run
(``rankgame preferences``). The result is an ordinary trajectory file (see
:mod:`rankgame.data.trajectories`); :func:`ranking_order` orders its trajectories from worst to best,
by their returns or, for rankings given by people, by an optional ``ranks`` list in the metadata
(higher is better). The shipped files, one ``<env_id>.npz`` per task, keep the command that made them.
"""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Any

import numpy as np

from rankgame.checkpoint import load_checkpoint
from rankgame.data import shipped_path
from rankgame.data.minari import is_minari_ref, minari_dataset_id, read_minari
from rankgame.data.trajectories import Trajectory, TrajectoryFile, load_trajectories, save_trajectories
from rankgame.envs.make import env_spec, make_env
from rankgame.envs.rollout import to_env_action
from rankgame.errors import RankGameError

PREFERENCE_DIR = Path(__file__).parent


def shipped_preferences_path(env_id: str) -> Path:
    """Path of the shipped preference file of ``env_id``; a :class:`RankGameError` if there is none."""
    instead = "make a file with `rankgame preferences` and pass it with --preferences"
    return shipped_path(PREFERENCE_DIR, env_id, "preference data", instead)


def ranking_order(data: TrajectoryFile) -> np.ndarray:
    """Indices ``(p,)`` of the file's trajectories from worst to best.

    The metadata's ``ranks`` (one number per trajectory, higher is better) decides if present;
    otherwise the true returns do. Ties keep the file's order.
    """
    ranks = data.metadata.get("ranks")
    if ranks is None:
        return np.argsort(data.returns, kind="stable")
    ranks = np.asarray(ranks, np.float64)
    if ranks.shape != (len(data.trajectories),) or not np.all(np.isfinite(ranks)):
        raise RankGameError(
            f"the preference file's 'ranks' must hold one finite number per trajectory "
            f"({len(data.trajectories)}), got {np.shape(ranks)}"
        )
    return np.argsort(ranks, kind="stable")


def episodes_from_replay(
    arrays: dict[str, np.ndarray], horizon: int, act_low: np.ndarray, act_high: np.ndarray, wrapped: bool
) -> list[Trajectory]:
    """The complete episodes stored in a replay buffer, in the order they were played.

    Args:
        arrays: the buffer's checkpoint arrays ``buffer/obs (N, obs_dim)``, ``buffer/acts (N, act_dim)``
            (normalized to ``[-1, 1]``), ``buffer/next_obs (N, obs_dim)``, ``buffer/dones (N,)``,
            ``buffer/rews (N,)`` and ``buffer/pos ()``.
        horizon: the task's time limit; an episode that neither terminated nor lasted this long is
            incomplete (the one being played when the checkpoint was taken) and is left out.
        act_low, act_high: ``(act_dim,)`` action bounds, to store actions in environment units.
        wrapped: whether the run wrote more transitions than the buffer holds (it then continues
            writing at ``buffer/pos``, which is where its oldest transition lies).

    An episode ends after transition ``i`` when it reached a terminal state, or when the next stored
    transition does not start where this one ended (a reset). A buffer that wrapped around has
    overwritten the start of its oldest episode, which is also left out.
    """
    order = np.arange(len(arrays["buffer/obs"]))
    if wrapped:
        order = np.roll(order, -int(arrays["buffer/pos"]))
    obs, acts, next_obs = (arrays[f"buffer/{key}"][order] for key in ("obs", "acts", "next_obs"))
    dones, rews = arrays["buffer/dones"][order] > 0.5, arrays["buffer/rews"][order]
    reset_after = np.zeros(len(order), bool)
    reset_after[:-1] = np.any(next_obs[:-1] != obs[1:], axis=1)
    ends = np.flatnonzero(dones | reset_after)
    starts = np.concatenate([[0], ends + 1])
    stops = np.concatenate([ends + 1, [len(order)]])
    episodes = []
    for k, (start, stop) in enumerate(zip(starts, stops, strict=True)):
        length = stop - start
        if length == 0 or (k == 0 and wrapped):
            continue
        terminated = bool(dones[stop - 1])
        if not terminated and length != horizon:
            continue
        flags = np.zeros(length, bool)
        flags[-1] = True
        episodes.append(
            Trajectory(
                obs=np.concatenate([obs[start:stop], next_obs[stop - 1 : stop]]),
                acts=to_env_action(acts[start:stop], act_low, act_high).astype(np.float32),
                rews=rews[start:stop],
                terminated=flags if terminated else np.zeros(length, bool),
                truncated=np.zeros(length, bool) if terminated else flags,
            )
        )
    return episodes


def sample_preferences(run: Path, out: Path, count: int, seed: int, command: str | None = None) -> dict[str, Any]:
    """Draw ``count`` complete episodes uniformly, without replacement, from a ``rankgame expert`` run's
    replay buffer (``run/checkpoint.npz``) and write them to ``out`` with their provenance.

    Returns a summary: the number of episodes in the buffer and the returns drawn.
    """
    if count <= 1:
        raise RankGameError("--count must be at least 2: a ranking needs two trajectories")
    if seed < 0:
        raise RankGameError(f"--seed must be >= 0 (got {seed})")
    if not (Path(run) / "checkpoint.npz").is_file():
        raise RankGameError(f"no checkpoint.npz in {run}: pass the folder of a `rankgame expert` run")
    metadata, arrays = load_checkpoint(Path(run) / "checkpoint.npz", any_layout=True)  # buffer keys never changed
    env_id = metadata.get("config", {}).get("env")
    if not isinstance(env_id, str):
        raise RankGameError(f"{run}/checkpoint.npz does not say which environment it was trained on")
    env = make_env(env_id)
    spec = env_spec(env)
    env.close()
    if "buffer/rews" not in arrays:
        raise RankGameError(
            f"{run}/checkpoint.npz has no replay buffer with environment rewards: use a `rankgame expert` run"
        )
    if arrays["buffer/obs"].shape[1:] != (spec.obs_dim,):
        raise RankGameError(f"{run}/checkpoint.npz holds no replay buffer of {env_id} observations")
    horizon = spec.max_episode_steps or int(1e9)
    # An expert run stores one transition per environment step.
    wrapped = int(metadata.get("env_steps", 0)) > len(arrays["buffer/obs"])
    episodes = episodes_from_replay(arrays, horizon, spec.act_low, spec.act_high, wrapped)
    if len(episodes) < count:
        raise RankGameError(f"the replay buffer holds {len(episodes)} complete episodes; --count asks for {count}")
    chosen = np.sort(np.random.default_rng(seed).choice(len(episodes), size=count, replace=False))
    drawn = [episodes[i] for i in chosen]
    save_trajectories(
        out,
        env_id,
        drawn,
        source="sac-replay",
        command=command or shlex.join(["rankgame", "preferences", "--run", str(run), "--count", str(count)]),
        sample_seed=seed,
        run_env_steps=int(metadata.get("env_steps", -1)),
        run_config=metadata.get("config", {}),
        replay_episodes=len(episodes),
        replay_indices=[int(i) for i in chosen],
    )
    returns = sorted(t.ret for t in drawn)
    return {"env": env_id, "replay_episodes": len(episodes), "drawn": count, "returns_worst_to_best": returns}


def load_preferences(path: Path | str, env_id: str) -> tuple[TrajectoryFile, np.ndarray]:
    """Read a preference file for ``env_id`` (or the local Minari dataset it names as ``minari:DATASET_ID``,
    ranked by its ``ranks`` if it was written from a file that had them, else by returns): the file and its
    worst-to-best order ``(p,)``."""
    data = read_minari(minari_dataset_id(path), env_id) if is_minari_ref(path) else load_trajectories(path, env_id)
    if len(data.trajectories) < 2:
        raise RankGameError(f"{path} holds {len(data.trajectories)} trajectory; a ranking needs at least 2")
    return data, ranking_order(data)
