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
