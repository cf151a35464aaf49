"""Swappable sources of the ``grid`` observation behind one interface (``space()``, ``observe()``).

Like HighwayEnv's observation types: the env asks its source for the space once and for a grid each
control step, and does not care whether the grid is the ground truth or the detectors' output.

- :class:`OracleSource` rasterises the terrain's ground-truth records (:class:`~negobs_gym.envs.
  observation.OracleGrid`), for ablations;
- :class:`DetectorSource` casts the LiDAR rig and runs both papers' detectors
  (:class:`~negobs_gym.envs.perception.DetectorGrid`), as on a real vehicle;
- :class:`PemSource` rasterises the ground truth and applies a perception-error model of the
  detector's ``negative`` channel (:class:`~negobs_gym.envs.pem.PemGrid`), at the oracle's cost.

A new source subclasses :class:`GridSource` and is added to :data:`GRID_SOURCES` under the name
``ObservationConfig.source`` selects it by.
"""

from __future__ import annotations

import abc
import dataclasses

import numpy as np
from gymnasium import spaces

from negobs_gym.core.pose import Pose
from negobs_gym.envs.observation import OracleGrid, grid_space, stack_channels
from negobs_gym.envs.pem import PemGrid, load_pem
from negobs_gym.envs.perception import DetectorGrid, world_products
from negobs_gym.envs.phantoms import Phantoms
from negobs_gym.errors import ConfigError
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle
from negobs_gym.sim.world import World
from negobs_gym.spec import CHANNELS, ObservationConfig

__all__ = ["GRID_SOURCES", "DetectorSource", "GridSource", "OracleSource", "PemSource", "make_grid_source"]


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

    def hazards(self):
        """What the safety filter reads (``negative_cells_xy_m()``, ``positive_cells_xy_m()``,
        ``stamp_s``, ``observed``, ``pose``), when this source provides it; None (default): the env
        runs the detectors beside it for the hazards."""
        return None


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

    def hazards(self) -> DetectorGrid | None:
        return self.perception


class PemHazards:
    """The PEM source's last frame as the safety filter reads it: its own cells, no detector. The
    cells and the coverage are computed when first asked for (only a filtered episode asks)."""

    def __init__(self, grid, oracle: OracleGrid | None = None) -> None:
        self._grid = grid
        self._oracle = oracle
        self.stamp_s: float | None = None
        self.pose: Pose | None = None
        self._layers: dict[str, np.ndarray] = {}
        self._cells: dict[str, np.ndarray] = {}
        self._observed: np.ndarray | None = None

    def update(self, negative: np.ndarray, positive: np.ndarray, pose: Pose, stamp_s: float) -> None:
        """This frame's layers, drawn around the true ``pose`` (the cells' frame)."""
        self._layers = {"negative": negative, "positive": positive}
        self._cells, self._observed = {}, None
        self.pose, self.stamp_s = pose, stamp_s

    def _cells_of(self, name: str) -> np.ndarray:
        if name not in self._cells:
            layer = self._layers.get(name)
            self._cells[name] = self._grid.centres_of(layer) if layer is not None else np.empty((0, 2))
        return self._cells[name]

    @property
    def observed(self) -> np.ndarray | None:
        """The oracle's ``observed`` layer of the last frame (inside the heightfield), for the
        governed filter's coverage."""
        if self._observed is None and self.pose is not None and self._oracle is not None:
            self._observed = self._oracle.layers(self.pose, ("observed",))["observed"]
        return self._observed

    def negative_cells_xy_m(self) -> np.ndarray:
        """(N, 2) vehicle-frame centres of this frame's PEM ``negative`` cells."""
        return self._cells_of("negative")

    def positive_cells_xy_m(self) -> np.ndarray:
        """(N, 2) centres of this frame's ``positive`` cells (the PEM's, or the oracle's where the
        model draws no ``positive`` channel; see :class:`PemSource`)."""
        return self._cells_of("positive")


class PemSource(GridSource):
    """The ground truth rasterised around the true pose, its obstacle channels passed through the
    perception-error model of ``config.pem_model`` (:class:`~negobs_gym.envs.pem.PemGrid`, one per
    channel the model draws: ``negative``, and ``positive`` when the file has it).

    Loading the model checks it against ``config``'s detector settings (a mismatch is a
    :class:`~negobs_gym.errors.ConfigError` naming it). ``traversable`` and ``observed`` are the
    oracle's (the ground truth), and so is ``positive`` under a model without that channel. The
    model draws from a child of the sensors' generator (each channel from a child of that), so the
    sensors' stream stays as it was. Every step is a frame (``scan_every`` is ignored). The safety
    filter's hazards are this source's own cells (:meth:`hazards`): no detector runs beside it.
    """

    def __init__(self, config: ObservationConfig) -> None:
        super().__init__(config)
        self.model = load_pem(config.pem_model, config)
        self._oracle_config = dataclasses.replace(
            config,
            source="oracle",
            oracle_range_m=None,
            phantoms=dataclasses.replace(config.phantoms, per_100m=0.0),
        )
        self._hazards = PemHazards(config.grid)

    def start(
        self,
        world: World,
        vehicle: Vehicle,
        terrain: Terrain,
        rng: np.random.Generator,
        cache: dict | None = None,
    ) -> None:
        self._vehicle = vehicle
        self.oracle = OracleGrid(self._oracle_config, terrain)
        pem_rng = rng.spawn(1)[0]
        self.grid = PemGrid(self.model, self.config.grid, terrain, pem_rng, cache)
        self.positive_grid = (
            PemGrid(self.model, self.config.grid, terrain, pem_rng.spawn(1)[0], cache, channel="positive")
            if "positive" in self.model.channels
            else None
        )
        self._hazards = PemHazards(self.config.grid, self.oracle)

    def layers(self, timestamp_s: float) -> dict[str, np.ndarray]:
        pose = self._vehicle.true_pose()
        drawn = {"negative": self.grid.layer(pose)}
        if self.positive_grid is not None:
            drawn["positive"] = self.positive_grid.layer(pose)
        # the oracle's other channels, and positive for the hazards where the model has none
        names = tuple(
            c for c in CHANNELS if c not in drawn and (c == "positive" or c in self.config.channels)
        )
        layers = {**self.oracle.layers(pose, names), **drawn} if names else drawn
        self._hazards.update(layers["negative"], layers["positive"], pose, float(timestamp_s))
        return {name: layers[name] for name in self.config.channels}

    def hazards(self) -> PemHazards:
        return self._hazards


#: ``ObservationConfig.source`` -> the source class.
GRID_SOURCES: dict[str, type[GridSource]] = {
    "oracle": OracleSource,
    "detector": DetectorSource,
    "pem": PemSource,
}


def make_grid_source(config: ObservationConfig) -> GridSource:
    """The source ``config.source`` names."""
    if config.source not in GRID_SOURCES:
        raise ConfigError("source", f"no grid source {config.source!r}; one of {sorted(GRID_SOURCES)}")
    return GRID_SOURCES[config.source](config)
