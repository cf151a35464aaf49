"""Built worlds kept between episodes, so a reset onto a terrain seen before skips the build.

Building an episode's world (terrain generation, PyBullet heightfield with its internal-edge map,
vehicle, settling, the Embree scene) takes ~1.2 s for OffroadNav's 120 m course; restoring a kept
one takes milliseconds. A world is keyed by what decides its episode draw (terrain, start pose and
speed): the env generator's state right before the scenario is drawn (so ``reset(seed=s)`` twice
hits), or the index of the draw in a fixed pool (the spec's ``episode.terrain_pool_size``). Right after
settling, the PyBullet state is saved (``saveState``); every episode on that world, the first
included, starts from ``restoreState``, so a kept world gives the same episode bit for bit as a
fresh one.

One more world may be held *ahead* (:meth:`WorldCache.hold_ahead`): the one the next reset will
draw, built while the process has nothing else to do (a vector-env worker waiting for the others
or for a policy update, :class:`~negobs_gym.envs.build_ahead.BuildAheadVecEnv`). The reset that draws
its key takes it like a kept world; any other reset closes it.

A world dropped from the cache frees its PyBullet and Embree memory into the C heap, where glibc
keeps most of it; :func:`release_freed_memory` hands it back to the OS, so a long run of resets
onto new terrains holds one world's memory, not the high-water mark of all the worlds it built.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pybullet as p

from negobs_gym.sim.events import EventMonitor
from negobs_gym.sim.types import Terrain
from negobs_gym.sim.vehicle import Vehicle, VehicleConfig
from negobs_gym.sim.world import World, WorldConfig
from negobs_gym.spec import SampledScenario

__all__ = ["CachedWorld", "WorldCache", "generator_key", "release_freed_memory"]


def generator_key(rng: np.random.Generator) -> str:
    """A digest of ``rng``'s bit-generator state: equal keys give equal draws."""
    return hashlib.sha1(repr(rng.bit_generator.state).encode()).hexdigest()


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    """glibc's ``malloc_trim``, or None where the C library has none (macOS, musl, Windows)."""
    try:
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):  # TypeError: Windows cannot open "no library"
        return None


def release_freed_memory() -> bool:
    """Return the C heap's free pages to the OS (glibc ``malloc_trim``); False where unavailable.

    Costs ~10 ms after a world is dropped (OffroadNav-v0), against ~0.6 s to build the next one.
    """
    trim = _malloc_trim()
    if trim is None:
        return False
    trim(0)
    return True


@dataclass(eq=False)
class CachedWorld:
    """One settled world: its episode draw, vehicle, event monitor and the saved settled state."""

    episode: SampledScenario
    world: World
    vehicle: Vehicle
    monitor: EventMonitor
    settled_state_id: int
    settled_time_s: float
    rng_state_after_draw: dict[str, Any] | None = None
    extras: dict[str, Any] = field(default_factory=dict)  # per-world products (ray caster, ...)

    @property
    def terrain(self) -> Terrain:
        """The episode's terrain."""
        return self.episode.terrain

    def restore(self) -> None:
        """Back to the settled state, vehicle at rest with no command (the start of an episode)."""
        p.restoreState(self.settled_state_id, physicsClientId=self.world.client_id)
        self.world.sim_time_s = self.settled_time_s
        self.vehicle.apply(0.0, 0.0, 0.0)
        self.monitor.reset()
        self.monitor.poll()

    def close(self) -> None:
        """Release the PyBullet client."""
        self.monitor.detach()
        self.world.close()


class WorldCache:
    """At most ``max_worlds`` settled worlds, least recently used dropped (and closed) first, and
    at most one world held ahead of the reset that will draw it."""

    def __init__(self, max_worlds: int) -> None:
        self.max_worlds = max_worlds
        self._worlds: OrderedDict[str, CachedWorld] = OrderedDict()
        self._ahead: tuple[str, CachedWorld] | None = None
        self.hits = 0
        self.misses = 0
        self.evictions = 0  # worlds dropped and closed so far
        self.ahead_hits = 0  # gets answered by the world held ahead (counted in hits too)

    def __len__(self) -> int:
        return len(self._worlds)

    def __contains__(self, key: str) -> bool:
        return key in self._worlds or (self._ahead is not None and self._ahead[0] == key)

    def get(self, key: str) -> CachedWorld | None:
        """The world under ``key`` (now most recently used), or None.

        The world held ahead under ``key`` joins the kept worlds here (closing the least recently
        used beyond ``max_worlds``); held under another key, it can no longer be drawn and is closed.
        """
        if self._ahead is not None and self._ahead[0] == key:
            ahead, self._ahead = self._ahead[1], None
            self.hits += 1
            self.ahead_hits += 1
            self.put(key, ahead)
            return ahead
        self._drop_ahead()
        entry = self._worlds.get(key)
        if entry is None:
            self.misses += 1
            return None
        self.hits += 1
        self._worlds.move_to_end(key)
        return entry

    def counts(self) -> dict[str, int]:
        """Kept worlds, hits (``ahead_hits`` of them on the world held ahead), misses, evictions."""
        return {
            "kept": len(self._worlds),
            "held_ahead": int(self._ahead is not None),
            "hits": self.hits,
            "ahead_hits": self.ahead_hits,
            "misses": self.misses,
            "evictions": self.evictions,
        }

    def hold_ahead(self, key: str, entry: CachedWorld) -> None:
        """Keep ``entry`` for the reset that will ask for ``key`` (replacing, and closing, any
        world held ahead before)."""
        self._drop_ahead()
        self._ahead = (key, entry)

    def _drop_ahead(self) -> None:
        """Close the world held ahead, if any."""
        if self._ahead is not None:
            self._ahead[1].close()
            self._ahead = None
            self.evictions += 1

    def put(self, key: str, entry: CachedWorld) -> None:
        """Add ``entry`` as the most recently used; closes the least recently used beyond the limit.

        The env calls it on reset, when the world of the episode that ended is no longer needed:
        with ``max_worlds = 1`` that world is closed here and one world stays alive.
        """
        self._worlds[key] = entry
        self._worlds.move_to_end(key)
        while len(self._worlds) > self.max_worlds:
            _, old = self._worlds.popitem(last=False)
            old.close()
            self.evictions += 1

    def close(self) -> None:
        """Close every kept world and the one held ahead."""
        for entry in self._worlds.values():
            entry.close()
        self._worlds.clear()
        self._drop_ahead()


def build_world(
    episode: SampledScenario, world_config: WorldConfig, vehicle_config: VehicleConfig, settle_steps: int
) -> CachedWorld:
    """Build, settle and save a world on the episode's terrain, the vehicle at its start pose.

    With INS noise configured the vehicle gets a placeholder generator: the env hands it the
    episode's own with :meth:`~negobs_gym.sim.vehicle.Vehicle.use_ins_rng` before any draw.
    """
    world = World(episode.terrain, world_config)
    try:
        noisy = vehicle_config.ins_position_noise_m > 0 or vehicle_config.ins_angle_noise_deg > 0
        vehicle = Vehicle(world, vehicle_config, rng=np.random.default_rng(0) if noisy else None)
        vehicle.reset(episode.start_pose)
        monitor = EventMonitor(world, vehicle)
        world.step(settle_steps)
        state_id = p.saveState(physicsClientId=world.client_id)
    except BaseException:
        world.close()
        raise
    return CachedWorld(episode, world, vehicle, monitor, state_id, world.sim_time_s)
