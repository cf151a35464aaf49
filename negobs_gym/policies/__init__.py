"""Navigation policies that learn on the vehicle-centred grid: observation adapter, extractor, training.

- :mod:`negobs_gym.policies.observation`: :class:`PolicyObservation`, the wrapper that gives SB3 a
  flat grid (so SB3 does not take the 4 x 36 x 16 grid for an image) or drops it (state only), and
  :func:`match_observation` / :class:`PolicyDriver`, which feed a raw env observation to a model
  trained behind that wrapper (``negobs eval policy`` uses them);
- :mod:`negobs_gym.drivers.model`: :class:`ModelDriver`, a saved or shipped model as a
  driver (``negobs eval policy``, the braking campaign's ``sb3`` driver, ``negobs scenario run
  --policy``);
- :mod:`negobs_gym.policies.extractor`: :class:`GridStateExtractor`, a small CNN over the grid
  plus the scaled state vector, an SB3 ``BaseFeaturesExtractor`` for ``MultiInputPolicy``;
- :mod:`negobs_gym.policies.training`: :func:`train` behind ``negobs train`` and
  ``examples/train_ppo.py`` (PPO or SAC, vector envs, logs, periodic evaluation, checkpoints,
  resume).

Configs (no torch, no gymnasium) are in :mod:`negobs_gym.policies.config`. The names below are
imported on first use, so ``negobs --help`` does not load gymnasium.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["PolicyDriver", "PolicyObservation", "match_observation"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module("negobs_gym.policies.observation"), name)
    raise AttributeError(f"module 'negobs_gym.policies' has no attribute {name!r}")
