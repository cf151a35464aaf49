"""PyBullet backend: ``rayTestBatch`` with numpy arrays, in chunks of at most 16383 rays.

A batch of exactly 16384 rays returns one result short (bullet3 issue 4215), hence the chunk cap.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
import pybullet as p

from negobs_gym.sensors.raycast.base import check_rays

MAX_BATCH = 16383  # bullet3 issue 4215


class PyBulletCaster:
    """Ray caster over a live PyBullet client; bodies in ``exclude_body_ids`` are treated as misses.

    Excluded bodies (the vehicle's own body) are removed by recasting from just past the hit.
    """

    def __init__(self, client_id: int, exclude_body_ids: Iterable[int] = (), num_threads: int = 0) -> None:
        self.client_id = int(client_id)
        self.exclude = frozenset(int(b) for b in exclude_body_ids)
        self.num_threads = int(num_threads)

    def _batch(self, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        body = np.full(len(start), -1, dtype=np.int64)
        frac = np.ones(len(start))
        for i in range(0, len(start), MAX_BATCH):
            res = p.rayTestBatch(
                start[i : i + MAX_BATCH],
                end[i : i + MAX_BATCH],
                numThreads=self.num_threads,
                physicsClientId=self.client_id,
            )
            body[i : i + len(res)] = [r[0] for r in res]
            frac[i : i + len(res)] = [r[2] for r in res]
        return body, frac

    def cast(self, origins: np.ndarray, directions: np.ndarray, max_range_m: float) -> np.ndarray:
        """Ranges [m] of first hits (NaN = miss or only excluded bodies within range)."""
        o, d = check_rays(origins, directions, max_range_m)
        out = np.full(len(o), np.nan)
        offset = np.zeros(len(o))
        todo = np.arange(len(o))
        for _ in range(8):  # each pass steps past one excluded body
            if todo.size == 0:
                break
            start = o[todo] + d[todo] * offset[todo, None]
            end = o[todo] + d[todo] * max_range_m
            body, frac = self._batch(start, end)
            dist = offset[todo] + frac * (max_range_m - offset[todo])
            hit = body >= 0
            excl = hit & np.isin(body, list(self.exclude)) if self.exclude else np.zeros_like(hit)
            good = hit & ~excl
            out[todo[good]] = dist[good]
            offset[todo[excl]] = dist[excl] + 1e-3
            todo = todo[excl]
        return out
