"""Deprecated: the shipped policies and their records moved to :mod:`negobs_gym.drivers.zoo`."""

import warnings

from negobs_gym.drivers.zoo import *  # noqa: F403 - the old import path, kept for one release
from negobs_gym.drivers.zoo import __all__  # noqa: F401

warnings.warn(
    "negobs_gym.policies.baselines moved to negobs_gym.drivers.zoo; import from there",
    DeprecationWarning,
    stacklevel=2,
)
