"""Env classes behind the old ids of renamed tasks (:data:`negobs_gym.registration.ALIASES`).

Each is the new id's class, unchanged, except that building it warns once per process that the
old id is deprecated (:func:`negobs_gym.registration.warn_alias`).
"""

from __future__ import annotations

from typing import Any

from negobs_gym.envs.scenarios import OffroadTrackEnv
from negobs_gym.registration import warn_alias

__all__ = ["OffroadNavV2Alias"]


class OffroadNavV2Alias(OffroadTrackEnv):
    """``negobs_gym/OffroadNav-v2``: the old id of ``negobs_gym/OffroadTrack-v0`` (same env)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        warn_alias("negobs_gym/OffroadNav-v2")
        super().__init__(*args, **kwargs)
