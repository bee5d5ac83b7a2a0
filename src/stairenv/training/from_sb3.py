"""A Stable-Baselines3 PPO checkpoint (``baselines/train_sb3.py``) as a lean-trainer state, so that a
run started with SB3 goes on with ``stairenv.training`` (``train_ppo.py --init-from ppo_<n>_steps.zip``).

The networks are the same (``ActorCritic`` mirrors SB3's ``MlpPolicy`` with separate ReLU networks, in
the same parameter order, so the Adam state carries over too); the VecNormalize statistics become the
normalisers; the AMP state saved beside the checkpoint the discriminator. The .zip and the VecNormalize
.pkl are pickles (SB3's formats): opening them can run code, so convert only files you trust.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from stairenv.style.wrappers import read_amp_state

#: SB3 MlpPolicy parameter names -> ActorCritic's
_NAMES = {"mlp_extractor.policy_net.": "policy_net.", "mlp_extractor.value_net.": "value_net.",
          "action_net.": "action_mean.", "value_net.": "value."}


def _rename(key: str) -> str:
    for old, new in _NAMES.items():
        if key.startswith(old):
            return new + key[len(old):]
    return key


def _rms_state(rms) -> dict[str, Any]:
    return {"mean": torch.as_tensor(np.asarray(rms.mean, dtype=np.float64)),
            "var": torch.as_tensor(np.asarray(rms.var, dtype=np.float64)), "count": float(rms.count)}


def state_from_sb3(checkpoint: Path, statistics: Path, amp_state: Path | None) -> dict[str, Any]:
    """The weights-only part of a lean checkpoint (model, optimiser, normalisers, discriminator) from an
    SB3 PPO ``.zip``, its VecNormalize ``.pkl`` and, with AMP, its AMP state ``.pt``."""
    from stable_baselines3 import PPO

    from stairenv.policy_loading import read_normalizer

    model = PPO.load(str(checkpoint), device="cpu")
    weights = {_rename(k): v.detach().clone() for k, v in model.policy.state_dict().items()}
    normalizer = read_normalizer(statistics)
    style = None
    if amp_state is not None:
        saved = read_amp_state(amp_state)
        style = {"discriminator": saved["discriminator"], "config": saved["config"], "rounds": saved["rounds"]}
    return {"model": weights, "optimizer": model.policy.optimizer.state_dict(),
            "obs_rms": _rms_state(normalizer.obs_rms), "ret_rms": _rms_state(normalizer.ret_rms), "style": style,
            "hidden": [layer.out_features for layer in model.policy.mlp_extractor.policy_net
                       if isinstance(layer, torch.nn.Linear)]}
