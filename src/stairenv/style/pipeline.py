"""Left over from pipelined AMP scoring, which was removed: only ``PIPELINE_CHOICES`` remains, for
``baselines/train_ppo.py``'s ``--disc-pipeline`` flag until that flag goes (then delete this module).

Pipelined scoring (a worker thread scoring each env's window while the next env of a
``DummyVecEnv`` stepped) did not beat scoring a step's N windows in one call on the batched env
(``benchmarks/bench_amp_batch.py``); the style wrappers take no ``pipeline`` keyword.
"""

from __future__ import annotations

PIPELINE_CHOICES = ("auto", "on", "off")
