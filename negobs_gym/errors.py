"""Exception hierarchy of negobs_gym.

Every error the package raises on purpose derives from :class:`NegobsError`, so callers can catch
the package's own failures in one place. The concrete classes also derive from the built-in
exception a Python user would expect (``ValueError`` for bad values, ``ImportError`` for a missing
optional dependency).
"""

from __future__ import annotations


class NegobsError(Exception):
    """Base class of every error raised on purpose by negobs_gym."""


class ConfigError(NegobsError, ValueError):
    """A configuration value is invalid. ``field`` names the offending config field."""

    def __init__(self, field: str, message: str) -> None:
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def __reduce__(self) -> tuple:
        # pickled with the constructor's own arguments: an error raised in a worker process
        # (campaigns, scenario seeds, vector envs) reaches the parent as itself, not as a
        # TypeError from rebuilding it out of its one-string ``args``
        return type(self), (self.field, self.message)


class ScanError(NegobsError, ValueError):
    """A LiDAR scan (or the pose that comes with it) cannot be used as given."""


class ActionError(NegobsError, ValueError):
    """An action passed to an environment or driver is malformed (wrong shape, NaN, inf)."""


class GeometryError(NegobsError, ValueError):
    """A geometry input (points, polygon, polyline, frame) has the wrong shape or non-finite values."""


class SimulationError(NegobsError, RuntimeError):
    """The physics simulation is in a state it cannot continue from (e.g. closed world)."""


class UsageError(NegobsError, RuntimeError):
    """An object was used out of order (e.g. a video written to outside its ``with`` block); the
    message says what to call first."""


class ResetNeeded(UsageError):
    """An environment was used before ``reset()`` (or after ``close()``): call ``reset()`` first."""


class WorkerError(NegobsError, RuntimeError):
    """A worker process (of a vector env) raised; the message holds the worker's traceback."""


class MissingDependencyError(NegobsError, ImportError):
    """An optional dependency is needed for this feature; the message says what to install."""

    def __init__(self, package: str, feature: str) -> None:
        self.package = package
        self.feature = feature
        super().__init__(f"{feature} needs the optional package {package!r}: pip install {package}")

    def __reduce__(self) -> tuple:
        return type(self), (self.package, self.feature)  # as ConfigError's


class InterfaceError(NegobsError, TypeError):
    """An object passed in lacks the interface needed (e.g. an env without ``hazard_state()``)."""


class UnknownNameError(NegobsError, KeyError):
    """A lookup by name found nothing (e.g. a sensor mount a rig does not have)."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0]) if self.args else ""


def require(condition: bool, field: str, message: str) -> None:
    """Raise :class:`ConfigError` for ``field`` unless ``condition`` holds (config validation)."""
    if not condition:
        raise ConfigError(field, message)
