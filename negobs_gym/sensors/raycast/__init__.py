"""Ray-casting backends behind one interface (see :mod:`.base`).

``make_caster(world, backend=...)`` picks one: ``"embree"`` (fast, needs ``embreex``),
``"pybullet"`` (the reference, sees every body exactly as the physics does) or ``"auto"`` (Embree
where ``embreex`` is installed, otherwise PyBullet).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import TYPE_CHECKING, Literal

from negobs_gym.errors import ConfigError, MissingDependencyError
from negobs_gym.sensors.raycast.base import RayCaster, check_rays

if TYPE_CHECKING:
    from negobs_gym.sim.world import World

__all__ = ["BACKENDS", "RayCaster", "check_rays", "make_caster"]

log = logging.getLogger(__name__)

Backend = Literal["auto", "embree", "pybullet"]
BACKENDS: tuple[str, ...] = ("auto", "embree", "pybullet")


def make_caster(
    world: World,
    backend: Backend = "auto",
    exclude_body_ids: Iterable[int] = (),
    threads: int = 1,
    isa: str = "native",
    fast_terrain: bool = True,
) -> RayCaster:
    """A ray caster over ``world`` that never sees the bodies in ``exclude_body_ids``.

    ``threads`` > 1 splits each Embree cast over that many threads; ``isa`` pins Embree's kernels
    (``EmbreeConfig.isa``); ``fast_terrain`` is ``EmbreeConfig.fast_terrain``. The PyBullet
    backend ignores all three.

    Raises:
        ConfigError: Unknown ``backend``.
        MissingDependencyError: ``backend="embree"`` without ``embreex`` installed.
    """
    if backend not in BACKENDS:
        raise ConfigError("backend", f"unknown ray-cast backend {backend!r}; expected one of {BACKENDS}")
    exclude = tuple(int(b) for b in exclude_body_ids)
    if backend in ("auto", "embree"):
        from negobs_gym.sensors.raycast.embree_backend import EmbreeCaster, EmbreeConfig

        try:
            return EmbreeCaster.from_world(
                world,
                exclude_body_ids=exclude,
                config=EmbreeConfig(threads=threads, isa=isa, fast_terrain=fast_terrain),
            )
        except MissingDependencyError:
            if backend == "embree":
                raise
            log.info("embreex is not installed: using the PyBullet ray-cast backend")
    from negobs_gym.sensors.raycast.pybullet_backend import PyBulletCaster

    return PyBulletCaster(world.client_id, exclude_body_ids=exclude)
