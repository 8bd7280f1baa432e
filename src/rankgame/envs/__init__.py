"""Environments: the factory for Gymnasium tasks, rollouts, and small built-in test tasks."""

from rankgame.envs.manipulation import register_manipulation_envs
from rankgame.envs.toy import register_toy_envs
from rankgame.envs.variants import register_variant_envs

register_toy_envs()
register_variant_envs()
register_manipulation_envs()
