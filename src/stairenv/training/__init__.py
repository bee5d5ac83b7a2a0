"""The lean PPO + AMP trainer over the batched env's arrays (``baselines/train_ppo.py``'s default).

``TrainConfig`` (``config.py``) holds a run's settings; ``Trainer`` (``ppo.py``) the loop, its
networks, normalisers and checkpoints. Needs the ``train`` extra (torch).
"""

from stairenv.training.config import TrainConfig
from stairenv.training.ppo import (CheckpointError, RunLog, Trainer, build_style, check_checkpoint, checkpoints_in,
                                   make_env, read_checkpoint)

__all__ = ["CheckpointError", "RunLog", "TrainConfig", "Trainer", "build_style", "check_checkpoint", "checkpoints_in",
           "make_env", "read_checkpoint"]
