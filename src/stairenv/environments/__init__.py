"""Gymnasium environments, one per module."""

from stairenv.environments.interlevel import InterLevelEnv

__all__ = ["InterLevelEnv"]
