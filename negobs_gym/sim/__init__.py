"""Simulator: procedural terrain, obstacles, scenario presets, rendering (and the PyBullet world)."""

from negobs_gym.sim.carving import NegativeObstacleSpec, PositiveObstacleSpec
from negobs_gym.sim.presets import PRESETS
from negobs_gym.sim.render import draw_terrain, render_top_down
from negobs_gym.sim.terrain import (
    BendSpec,
    BorderConfig,
    RoughnessConfig,
    TerrainConfig,
    generate_terrain,
    track_coordinates,
)
from negobs_gym.sim.types import (
    HeightField,
    NegativeObstacle,
    PositiveObstacle,
    Terrain,
    Track,
)

__all__ = [
    "PRESETS",
    "BendSpec",
    "BorderConfig",
    "HeightField",
    "NegativeObstacle",
    "NegativeObstacleSpec",
    "PositiveObstacle",
    "PositiveObstacleSpec",
    "RoughnessConfig",
    "Terrain",
    "TerrainConfig",
    "Track",
    "draw_terrain",
    "generate_terrain",
    "render_top_down",
    "track_coordinates",
]

# The physics names import pybullet; load them on first use so terrain-only users do not pay for it.
_PHYSICS = {
    "World": "negobs_gym.sim.world",
    "WorldConfig": "negobs_gym.sim.world",
    "Vehicle": "negobs_gym.sim.vehicle",
    "VehicleConfig": "negobs_gym.sim.vehicle",
    "EventConfig": "negobs_gym.sim.events",
    "EventMonitor": "negobs_gym.sim.events",
    "StepEvents": "negobs_gym.sim.events",
}
__all__ += sorted(_PHYSICS)


def __getattr__(name: str):  # PEP 562 lazy attributes
    if name in _PHYSICS:
        import importlib

        return getattr(importlib.import_module(_PHYSICS[name]), name)
    raise AttributeError(f"module 'negobs_gym.sim' has no attribute {name!r}")
