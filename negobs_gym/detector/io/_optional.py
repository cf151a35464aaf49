"""Imports of the ``negobs_gym[real]`` extra, failing with a message that says what to install."""

from __future__ import annotations

import importlib
from types import ModuleType

from negobs_gym.errors import MissingDependencyError


def optional_import(module: str, package: str, feature: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingDependencyError` naming ``package`` (and the extra)."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise MissingDependencyError(package, f"{feature} (extra negobs_gym[real])") from error
