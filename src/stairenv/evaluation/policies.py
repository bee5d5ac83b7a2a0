"""Policy loading moved to :mod:`stairenv.policy_loading` (below ``stories``, ``evaluation`` and
``training``); this module keeps the old import path working."""

from stairenv.policy_loading import (
    BUILTIN_POLICIES,
    Policy,
    RandomPolicy,
    SB3Policy,
    ZeroPolicy,
    load_policy,
    normalizer_beside,
    policy_label,
    read_normalizer,
)

__all__ = [
    "BUILTIN_POLICIES", "Policy", "RandomPolicy", "SB3Policy", "ZeroPolicy", "load_policy",
    "normalizer_beside", "policy_label", "read_normalizer",
]
