"""Shared fixtures: small SAC settings that compile and run in seconds."""

from __future__ import annotations

import pytest

import rankgame.envs  # noqa: F401  (registers the toy tasks)
from rankgame.policy.sac import SACConfig, sac_preset


@pytest.fixture
def tiny_sac() -> SACConfig:
    """A small SAC for the toy task: learns it in about a thousand steps."""
    return sac_preset(
        "paper",
        hidden_sizes=(64, 64),
        batch_size=64,
        start_steps=400,
        update_after=400,
        update_every=40,
        buffer_size=10_000,
    )
