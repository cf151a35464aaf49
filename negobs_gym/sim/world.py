"""The PyBullet world: one physics client holding the terrain, static obstacles and the vehicle.

The physics heightfield is the terrain's fine (ray-cast) heightfield resampled to
``WorldConfig.physics_resolution_m`` (0.25 m by default). PyBullet builds a render mesh for every
heightfield even in DIRECT mode, so a 200 m course at the terrain's 0.1 m takes 5–19 s and 1.3–2.8 GB;
at 0.25 m a new 200 m winding course is generated and built in about 1.5 s (numbers in
``docs/physics.md``). Ground truth and physics share the world frame of
:class:`~negobs_gym.sim.types.Terrain`.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pybullet as p

from negobs_gym.errors import ConfigError, SimulationError, require
from negobs_gym.sim.types import HeightField, PositiveObstacle, Terrain

__all__ = ["World", "WorldConfig", "physics_heightfield"]

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class WorldConfig:
    """Settings of the physics world.

    Attributes:
        time_step_s: Physics step [s]; 1/240 or 1/120 s are stable with the vehicle's suspension.
        gui: Open the PyBullet GUI instead of a headless DIRECT client.
        physics_resolution_m: Grid spacing of the physics heightfield [m]; the terrain's finer grid
            stays the ray-cast ground truth. Must not be finer than the terrain's own resolution.
        terrain_friction: Lateral friction of the ground and obstacles. PyBullet multiplies the two
            bodies' coefficients, so 1.0 here leaves the tyre's mu = 0.65 (paper N §4) effective.
        gravity_mps2: Gravity [m/s^2] (paper N Eq. 18 uses g = 9.81).
        solver_iterations: Constraint solver iterations per step.
        pybullet_renderer: Keep PyBullet's built-in software renderer (TinyRenderer, behind
            ``p.getCameraImage`` and ``p.getVisualShapeData``) in a DIRECT client. negobs renders
            with matplotlib and casts its own rays, so it is dropped by default: it copies every
            visual shape, the terrain's ~0.2 M triangles included, at ~0.1 s and ~115 MB per world
            (docs/physics.md, "Design choices"). The GUI keeps its renderer either way.
    """

    time_step_s: float = 1.0 / 240.0
    gui: bool = False
    physics_resolution_m: float = 0.25
    terrain_friction: float = 1.0
    gravity_mps2: float = 9.81  # paper N Eq. 18
    solver_iterations: int = 50
    pybullet_renderer: bool = False

    def __post_init__(self) -> None:
        require(
            math.isfinite(self.time_step_s) and 1.0 / 1000.0 <= self.time_step_s <= 1.0 / 60.0,
            "time_step_s",
            f"must be in [1/1000, 1/60] s (1/240 or 1/120 recommended), got {self.time_step_s}",
        )
        require(isinstance(self.gui, bool), "gui", f"must be a bool, got {self.gui!r}")
        require(
            math.isfinite(self.physics_resolution_m) and 0.01 <= self.physics_resolution_m <= 2.0,
            "physics_resolution_m",
            f"must be in [0.01, 2] m, got {self.physics_resolution_m}",
        )
        require(
            math.isfinite(self.terrain_friction) and self.terrain_friction > 0,
            "terrain_friction",
            f"must be > 0, got {self.terrain_friction}",
        )
        require(
            math.isfinite(self.gravity_mps2) and self.gravity_mps2 > 0,
            "gravity_mps2",
            f"must be > 0, got {self.gravity_mps2}",
        )
        require(
            isinstance(self.solver_iterations, int) and self.solver_iterations >= 1,
            "solver_iterations",
            f"must be an int >= 1, got {self.solver_iterations!r}",
        )
        require(
            isinstance(self.pybullet_renderer, bool),
            "pybullet_renderer",
            f"must be a bool, got {self.pybullet_renderer!r}",
        )


def _drop_software_renderer(client: int) -> None:
    """Unloads the TinyRenderer plugin that PyBullet links into every client: asking to load it by
    name returns the loaded one's id. Without an active renderer PyBullet skips building the render
    copies of visual shapes; physics is unchanged (episodes bit-identical, tests/sim/test_world.py)."""
    plugin = p.loadPlugin("tinyRendererPlugin", physicsClientId=client)
    if plugin >= 0:
        p.unloadPlugin(plugin, physicsClientId=client)


def physics_heightfield(heightfield: HeightField, resolution_m: float) -> HeightField:
    """Resample a terrain heightfield to the physics grid spacing.

    When ``resolution_m`` is an integer multiple of the terrain's spacing the result is a plain
    sub-sampling (samples are kept exactly, so flat pit floors keep their recorded depth);
    otherwise heights are bilinearly interpolated. The physics grid starts at the terrain origin.

    Raises:
        ConfigError: ``resolution_m`` is finer than the terrain's own resolution, or the terrain
            is too small to hold a 2 x 2 physics grid.
    """
    fine = heightfield.resolution_m
    if resolution_m < fine - 1e-9:
        raise ConfigError(
            "physics_resolution_m",
            f"{resolution_m} m is finer than the terrain's resolution {fine} m; use >= {fine}",
        )
    h = np.asarray(heightfield.heights_m)
    if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 2:
        raise ConfigError("terrain.heightfield", f"needs at least 2 x 2 samples, got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ConfigError("terrain.heightfield", "heights contain NaN or inf")
    ratio = resolution_m / fine
    stride = round(ratio)
    if abs(ratio - stride) < 1e-6:
        coarse = np.ascontiguousarray(h[::stride, ::stride], dtype=np.float32)
        return HeightField(heights_m=coarse, resolution_m=stride * fine, origin_m=heightfield.origin_m)
    x0, x1, y0, y1 = heightfield.extent_m
    nx = math.floor((x1 - x0) / resolution_m + 1e-9) + 1
    ny = math.floor((y1 - y0) / resolution_m + 1e-9) + 1
    if nx < 2 or ny < 2:
        raise ConfigError("physics_resolution_m", f"{resolution_m} m leaves fewer than 2 x 2 samples")
    xs = x0 + np.arange(nx) * resolution_m
    ys = y0 + np.arange(ny) * resolution_m
    gx, gy = np.meshgrid(xs, ys)
    coarse = heightfield.height_at(np.stack([gx, gy], axis=-1)).astype(np.float32)
    return HeightField(heights_m=coarse, resolution_m=resolution_m, origin_m=heightfield.origin_m)


class World:
    """One PyBullet client with a terrain body, static positive obstacles and dynamic bodies.

    Use as a context manager or call :meth:`close`; closing twice is harmless, any other use of a
    closed world raises :class:`~negobs_gym.errors.SimulationError`.

    Attributes exposed to the ray casters: ``client_id``, ``terrain``, ``terrain_body_id``,
    ``obstacle_body_ids`` (obstacle id -> body id) and :meth:`dynamic_body_ids`.
    """

    def __init__(self, terrain: Terrain, config: WorldConfig | None = None) -> None:
        self.config = config if config is not None else WorldConfig()
        if not isinstance(self.config, WorldConfig):
            raise ConfigError("config", f"must be a WorldConfig, got {type(self.config).__name__}")
        if not isinstance(terrain, Terrain):
            raise ConfigError("terrain", f"must be a Terrain, got {type(terrain).__name__}")
        self._client: int | None = None
        self._pre_step: list[Callable[[], None]] = []
        self._dynamic: list[int] = []
        self.terrain = terrain
        self.terrain_body_id = -1
        self.obstacle_body_ids: dict[str, int] = {}
        self.sim_time_s = 0.0
        mode = p.GUI if self.config.gui else p.DIRECT
        self._client = p.connect(mode)
        if self._client < 0:
            raise SimulationError("could not connect to PyBullet (a GUI may already be open)")
        try:
            if not (self.config.gui or self.config.pybullet_renderer):
                _drop_software_renderer(self._client)
            self._setup_physics()
            self._build_terrain(terrain)
        except BaseException:
            self.close()
            raise

    # -- lifecycle -----------------------------------------------------------------------------
    @property
    def client_id(self) -> int:
        """PyBullet physics client id (raises if the world is closed)."""
        if self._client is None:
            raise SimulationError("the world is closed")
        return self._client

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._client is None

    def close(self) -> None:
        """Disconnect the PyBullet client; idempotent."""
        if self._client is not None:
            try:
                p.disconnect(physicsClientId=self._client)
            finally:
                self._client = None
                self._pre_step.clear()
                self._dynamic.clear()

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # interpreter shutdown: pybullet may already be gone
            pass

    # -- building ------------------------------------------------------------------------------
    def _setup_physics(self) -> None:
        c = self.client_id
        p.resetSimulation(physicsClientId=c)
        p.setGravity(0.0, 0.0, -self.config.gravity_mps2, physicsClientId=c)
        p.setPhysicsEngineParameter(
            fixedTimeStep=self.config.time_step_s,
            numSolverIterations=self.config.solver_iterations,
            numSubSteps=0,
            physicsClientId=c,
        )

    def _build_terrain(self, terrain: Terrain) -> None:
        c = self.client_id
        hf = physics_heightfield(terrain.heightfield, self.config.physics_resolution_m)
        h = hf.heights_m
        ny, nx = h.shape
        h_min, h_max = float(h.min()), float(h.max())
        centre_z = 0.5 * (h_min + h_max)  # PyBullet centres the heightfield on (min + max) / 2
        res = hf.resolution_m
        shape = p.createCollisionShape(
            p.GEOM_HEIGHTFIELD,
            meshScale=[res, res, 1.0],
            heightfieldData=h.ravel().tolist(),
            numHeightfieldRows=nx,  # PyBullet's "rows" run along the fast (x) index
            numHeightfieldColumns=ny,
            flags=p.GEOM_CONCAVE_INTERNAL_EDGE,
            physicsClientId=c,
        )
        if shape < 0:
            raise SimulationError(f"PyBullet refused the {nx} x {ny} heightfield")
        base = [
            hf.origin_m[0] + 0.5 * (nx - 1) * res,
            hf.origin_m[1] + 0.5 * (ny - 1) * res,
            centre_z,
        ]
        self.terrain_body_id = p.createMultiBody(0, shape, basePosition=base, physicsClientId=c)
        p.changeDynamics(
            self.terrain_body_id, -1, lateralFriction=self.config.terrain_friction, physicsClientId=c
        )
        self.physics_heightfield = hf
        self.obstacle_body_ids = {}
        for obstacle in terrain.positive_obstacles:
            if obstacle.in_heightfield:
                continue
            self.obstacle_body_ids[obstacle.obstacle_id] = self._build_obstacle(obstacle)
        log.debug("built %d x %d physics heightfield at %.3f m", nx, ny, res)

    def _build_obstacle(self, obstacle: PositiveObstacle) -> int:
        c = self.client_id
        half = np.asarray(obstacle.half_extents_m, dtype=np.float64).reshape(-1)
        centre = np.asarray(obstacle.centre_m, dtype=np.float64).reshape(-1)
        if half.shape != (3,) or centre.shape != (3,) or not (np.all(np.isfinite(half)) and np.all(half > 0)):
            raise ConfigError(
                f"positive_obstacles[{obstacle.obstacle_id}]",
                "centre_m and half_extents_m must be 3 finite values, half extents > 0",
            )
        if obstacle.shape == "box":
            shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half.tolist(), physicsClientId=c)
        elif obstacle.shape == "cylinder":
            shape = p.createCollisionShape(
                p.GEOM_CYLINDER, radius=float(half[0]), height=float(2 * half[2]), physicsClientId=c
            )
        else:
            raise ConfigError(
                f"positive_obstacles[{obstacle.obstacle_id}].shape", f"unknown shape {obstacle.shape!r}"
            )
        orn = p.getQuaternionFromEuler([0.0, 0.0, float(obstacle.yaw_rad)])
        body = p.createMultiBody(
            0, shape, basePosition=centre.tolist(), baseOrientation=orn, physicsClientId=c
        )
        p.changeDynamics(body, -1, lateralFriction=self.config.terrain_friction, physicsClientId=c)
        return body

    # -- dynamic bodies and stepping -----------------------------------------------------------
    def add_dynamic_body(self, body_id: int) -> None:
        """Register a moving body (e.g. the vehicle) so ray casters know not to cache it."""
        self.client_id  # noqa: B018 - raises on a closed world
        self._dynamic.append(int(body_id))

    def add_step_hook(self, hook: Callable[[], None]) -> None:
        """Run ``hook()`` before every physics step (forces that PyBullet clears after each step)."""
        self.client_id  # noqa: B018
        self._pre_step.append(hook)

    def remove_step_hook(self, hook: Callable[[], None]) -> None:
        """Stop running a hook added with :meth:`add_step_hook` (no error if it is not there)."""
        if hook in self._pre_step:
            self._pre_step.remove(hook)

    def dynamic_body_ids(self) -> tuple[int, ...]:
        """Bodies that move (vehicles); the ray casters must not cache them."""
        self.client_id  # noqa: B018
        return tuple(self._dynamic)

    def step(self, n_steps: int = 1) -> None:
        """Advance physics by ``n_steps`` fixed time steps, running the pre-step hooks each time."""
        c = self.client_id
        if not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
            raise ConfigError("n_steps", f"must be an int >= 0, got {n_steps!r}")
        for _ in range(int(n_steps)):
            for hook in self._pre_step:
                hook()
            p.stepSimulation(physicsClientId=c)
            self.sim_time_s += self.config.time_step_s

    def ray_test_down(self, xy_m: np.ndarray, z_top_m: float = 50.0, z_bottom_m: float = -50.0) -> np.ndarray:
        """World Z where vertical rays at points (N, 2) first hit anything; NaN where none hit."""
        c = self.client_id
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        start = np.column_stack([xy, np.full(len(xy), z_top_m)])
        end = np.column_stack([xy, np.full(len(xy), z_bottom_m)])
        hits: list[Any] = p.rayTestBatch(start.tolist(), end.tolist(), physicsClientId=c)
        return np.array([h[3][2] if h[0] >= 0 else np.nan for h in hits], dtype=np.float64)

    def contacts(self, body_a: int, body_b: int, link_a: int | None = None) -> list[Any]:
        """PyBullet contact points between two bodies (optionally one link of ``body_a``)."""
        c = self.client_id
        if link_a is None:
            return list(p.getContactPoints(bodyA=body_a, bodyB=body_b, physicsClientId=c))
        return list(p.getContactPoints(bodyA=body_a, bodyB=body_b, linkIndexA=link_a, physicsClientId=c))
