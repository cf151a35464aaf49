"""Deprecated: :class:`ModelDriver` moved to :mod:`negobs_gym.drivers.model`."""

import warnings

from negobs_gym.drivers.model import ModelDriver

__all__ = ["ModelDriver"]

warnings.warn(
    "negobs_gym.policies.model_driver moved to negobs_gym.drivers.model; import from there",
    DeprecationWarning,
    stacklevel=2,
)
