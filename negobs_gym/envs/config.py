"""Deprecated: the episode configs moved to :mod:`negobs_gym.spec` (the scenario spec holds them).

The env is built from a spec plus overrides (``NegObsEnv(scenario=..., overrides=...)``,
:func:`negobs_gym.envs.make_env`); there is no separate env config object any more.
"""

import warnings

from negobs_gym.spec import (
    CHANNELS,
    ROUTE_MARGIN_M,
    EnvPhysicsConfig,
    ObservationConfig,
    PhantomConfig,
    RewardConfig,
)

__all__ = [
    "CHANNELS",
    "ROUTE_MARGIN_M",
    "EnvPhysicsConfig",
    "ObservationConfig",
    "PhantomConfig",
    "RewardConfig",
]

warnings.warn(
    "negobs_gym.envs.config moved to negobs_gym.spec; import the configs from there",
    DeprecationWarning,
    stacklevel=2,
)
