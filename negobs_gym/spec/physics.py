"""The physics world of an episode (``[physics]`` of a scenario spec)."""

from __future__ import annotations

from dataclasses import dataclass

from negobs_gym.sim.world import WorldConfig

__all__ = ["EnvPhysicsConfig"]


@dataclass(frozen=True, kw_only=True)
class EnvPhysicsConfig(WorldConfig):
    """The physics world of an env episode: :class:`~negobs_gym.sim.world.WorldConfig` at 1/120 s.

    12 sub-steps per 10 Hz control step instead of 24 of 1/240 s halve the physics cost; the
    full-brake distance from 25 km/h stays within 10 % of v^2 / (2 mu g) (docs/performance.md,
    ``tests/envs/test_physics_substeps.py``).
    """

    time_step_s: float = 1.0 / 120.0  # papers silent; see the docstring
