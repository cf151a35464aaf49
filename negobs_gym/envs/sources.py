"""Swappable sources of the ``grid`` observation behind one interface (``space()``, ``observe()``).

Like HighwayEnv's observation types: the env asks its source for the space once and for a grid each
control step, and does not care whether the grid is the ground truth or the detectors' output.

- :class:`OracleSource` rasterises the terrain's ground-truth records (:class:`~negobs_gym.envs.
  observation.OracleGrid`), for ablations;
- :class:`DetectorSource` casts the LiDAR rig and runs both papers' detectors
  (:class:`~negobs_gym.envs.perception.DetectorGrid`), as on a real vehicle.

A new source subclasses :class:`GridSource` and is added to :data:`GRID_SOURCES` under the name
``ObservationConfig.source`` selects it by.
"""

from __future__ import annotations

import abc

import numpy as np
from gymnasium import spaces

from negobs_gym.envs.observation import OracleGrid, grid_space, stack_channels
from negobs_gym.envs.perception import DetectorGrid, world_products
from negobs_gym.envs.phantoms import Phantoms
from negobs_gym.errors import ConfigError
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World
from negobs_gym.spec import ObservationConfig

__all__ = ["GRID_SOURCES", "DetectorSource", "GridSource", "OracleSource", "make_grid_source"]


class GridSource(abc.ABC):
    """Produces the vehicle-centred grid channels of :class:`ObservationConfig` each control step."""

    def __init__(self, config: ObservationConfig) -> None:
        self.config = config

    def space(self) -> spaces.Box:
        """The observation space of :meth:`observe` (uint8, channels x rows x cols)."""
        return grid_space(self.config)

    @abc.abstractmethod
    def start(
        self,
        world: World,
        vehicle: Vehicle,
        terrain: Terrain,
        rng: np.random.Generator,
        cache: dict | None = None,
    ) -> None:
        """Begin an episode in ``world`` (called at every reset; ``rng`` is the sensors' generator;
        ``cache`` is a dict kept with ``world`` across episodes, for products of the world such as
        the ray caster)."""

    def prepare(self, world: World, vehicle: Vehicle, cache: dict) -> None:
        """Build into ``cache`` the products of ``world`` that :meth:`start` will take from it, ahead
        of the episode (:meth:`~negobs_gym.envs.base.NegObsEnv.build_ahead`); none by default."""
        return

    @abc.abstractmethod
    def layers(self, timestamp_s: float) -> dict[str, np.ndarray]:
        """Full-resolution bool layers by channel name at the vehicle's current pose."""

    def observe(self, timestamp_s: float) -> np.ndarray:
        """The ``grid`` observation: uint8 (channels, rows, cols), max-pooled by ``downsample``."""
        return stack_channels(self.layers(timestamp_s), self.config)


class OracleSource(GridSource):
    """Ground truth rasterised around the vehicle's true pose (see :class:`OracleGrid`), with the
    config's phantoms, if any, in ``negative`` (:class:`~negobs_gym.envs.phantoms.Phantoms`)."""

    phantoms: Phantoms | None = None

    def start(
        self,
        world: World,
        vehicle: Vehicle,
        terrain: Terrain,
        rng: np.random.Generator,
        cache: dict | None = None,
    ) -> None:
        self._vehicle = vehicle
        self.grid = OracleGrid(self.config, terrain)
        if self.config.phantoms.enabled:
            # a child generator: the sensors' own stream (the hazards' detectors) stays as it was
            self.phantoms = Phantoms(self.config.phantoms, terrain.track, rng.spawn(1)[0])

    def layers(self, timestamp_s: float) -> dict[str, np.ndarray]:
        pose = self._vehicle.true_pose()
        layers = self.grid.layers(pose, self.config.channels)
        if self.phantoms is not None and "negative" in layers:
            phantom = self.phantoms.layer(pose, self.grid.cell_centres_v).reshape(layers["negative"].shape)
            layers["negative"] = layers["negative"] | phantom
        return layers


class DetectorSource(GridSource):
    """The LiDAR rig cast from the true pose and both detectors on the INS pose (:class:`DetectorGrid`).

    ``perception`` keeps the last frame (scans, detection) for the hazards and the renderer.
    """

    perception: DetectorGrid | None = None

    def start(
        self,
        world: World,
        vehicle: Vehicle,
        terrain: Terrain,
        rng: np.random.Generator,
        cache: dict | None = None,
    ) -> None:
        self.perception = DetectorGrid(self.config, world, vehicle, rng, cache=cache)

    def prepare(self, world: World, vehicle: Vehicle, cache: dict) -> None:
        world_products(self.config, world, vehicle, cache)

    def layers(self, timestamp_s: float) -> dict[str, np.ndarray]:
        return self.perception.observe(timestamp_s)


#: ``ObservationConfig.source`` -> the source class.
GRID_SOURCES: dict[str, type[GridSource]] = {"oracle": OracleSource, "detector": DetectorSource}


def make_grid_source(config: ObservationConfig) -> GridSource:
    """The source ``config.source`` names."""
    if config.source not in GRID_SOURCES:
        raise ConfigError("source", f"no grid source {config.source!r}; one of {sorted(GRID_SOURCES)}")
    return GRID_SOURCES[config.source](config)
