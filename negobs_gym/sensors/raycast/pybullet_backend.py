"""PyBullet backend: ``rayTestBatch`` with numpy arrays, in chunks of at most 16383 rays.

A batch of exactly 16384 rays returns one result short (bullet3 issue 4215), hence the chunk cap.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import numpy as np
import pybullet as p

from negobs_gym.errors import ConfigError
from negobs_gym.sensors.raycast.base import check_rays

log = logging.getLogger(__name__)

MAX_BATCH = 16383  # bullet3 issue 4215


class PyBulletCaster:
    """Ray caster over a live PyBullet client; bodies in ``exclude_body_ids`` are treated as misses.

    Rays whose closest hit is an excluded body (the vehicle's own body) are cast again asking
    PyBullet for every hit along them (``reportHitNumber`` = 0, 1, ... — PyBullet returns them
    in no particular order), and keep the nearest hit on a body that is not excluded. This is
    exact even for rays that cross the excluded body; recasting from just past the entry point
    is not, because a ray that starts inside a convex body does not hit its far side but can
    keep hitting the body's other links.
    """

    def __init__(
        self,
        client_id: int,
        exclude_body_ids: Iterable[int] = (),
        num_threads: int = 0,
        max_hits_per_ray: int = 64,
    ) -> None:
        self.client_id = int(client_id)
        self.exclude = frozenset(int(b) for b in exclude_body_ids)
        self.num_threads = int(num_threads)
        if max_hits_per_ray < 2:
            raise ConfigError("max_hits_per_ray", f"must be >= 2, got {max_hits_per_ray}")
        self.max_hits_per_ray = int(max_hits_per_ray)

    def _batch(
        self, start: np.ndarray, end: np.ndarray, hit_number: int = -1
    ) -> tuple[np.ndarray, np.ndarray]:
        body = np.full(len(start), -1, dtype=np.int64)
        frac = np.ones(len(start))
        extra = {} if hit_number < 0 else {"reportHitNumber": hit_number, "fractionEpsilon": 1e-9}
        for i in range(0, len(start), MAX_BATCH):
            res = p.rayTestBatch(
                start[i : i + MAX_BATCH],
                end[i : i + MAX_BATCH],
                numThreads=self.num_threads,
                physicsClientId=self.client_id,
                **extra,
            )
            body[i : i + len(res)] = [r[0] for r in res]
            frac[i : i + len(res)] = [r[2] for r in res]
        return body, frac

    def _is_excluded(self, body: np.ndarray) -> np.ndarray:
        if not self.exclude:
            return np.zeros(body.shape, dtype=bool)
        return np.isin(body, np.fromiter(self.exclude, dtype=np.int64))

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range_m: float) -> np.ndarray:
        """Ranges [m] of first hits (NaN = miss or only excluded bodies within range)."""
        o, d = check_rays(origins, directions, max_range_m)
        start, end = o, o + d * max_range_m
        body, frac = self._batch(start, end)
        out = np.where(body >= 0, frac * max_range_m, np.nan)
        todo = np.flatnonzero(self._is_excluded(body))
        if todo.size == 0:
            return out
        out[todo] = np.nan
        best = np.full(todo.size, np.inf)
        active = np.arange(todo.size)
        for n in range(self.max_hits_per_ray):
            body, frac = self._batch(start[todo[active]], end[todo[active]], hit_number=n)
            keep = (body >= 0) & ~self._is_excluded(body)
            best[active[keep]] = np.minimum(best[active[keep]], frac[keep])
            active = active[body >= 0]  # rays with no n-th hit have reported all their hits
            if active.size == 0:
                break
        else:
            log.warning(
                "%d rays have more than %d hits; farther hits ignored", active.size, self.max_hits_per_ray
            )
        hit = np.isfinite(best)
        out[todo[hit]] = best[hit] * max_range_m
        return out
