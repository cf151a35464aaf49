"""What a policy sees: the env's ``Dict(grid, state)`` with the grid flattened, or the state alone.

SB3 takes every 3-D ``Box`` for an image: its ``check_env`` warns about the grid's [0, 1] bounds
and its 36 x 16 size (images need [0, 255] and 36 x 36), and a ``CnnPolicy`` would divide by 255.
The grid is a set of binary occupancy maps, not an image, so :class:`PolicyObservation` hands SB3
a flat ``uint8`` vector of the same cells (SB3 casts it to float without scaling: 0 and 1 stay 0
and 1) and :class:`~negobs_gym.policies.extractor.GridStateExtractor` folds it back to
(channels, rows, cols) for its convolutions. The env itself keeps its documented space.
"""

from __future__ import annotations

from collections.abc import Mapping

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from negobs_gym.drivers.model import PolicyDriver, match_observation
from negobs_gym.errors import InterfaceError

__all__ = ["PolicyDriver", "PolicyObservation", "match_observation"]


class PolicyObservation(gym.ObservationWrapper):
    """``Dict(grid, state)`` -> ``Dict(grid=flat uint8, state)``, or ``Dict(state)`` when ``grid=False``.

    Args:
        env: An env whose observation space is a ``Dict`` with ``state`` (and ``grid`` when kept).
        grid: Keep the grid (flattened, C-order) or drop it (the state-only ablation).

    Attributes:
        grid_shape: (channels, rows, cols) of the env's grid, for the extractor to fold it back.
    """

    def __init__(self, env: gym.Env, *, grid: bool = True) -> None:
        super().__init__(env)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or "state" not in space.spaces:
            raise InterfaceError(
                f"env.observation_space: PolicyObservation needs a Dict space with 'state', got {space}"
            )
        if "grid" not in space.spaces or len(space["grid"].shape) != 3:
            raise InterfaceError(
                "env.observation_space: PolicyObservation needs a 3-D 'grid' Box (channels, rows, cols), "
                f"got {space}"
            )
        source = space["grid"]
        self.grid_shape: tuple[int, int, int] = tuple(source.shape)  # type: ignore[assignment]
        kept: dict[str, spaces.Space] = {}
        if grid:
            kept["grid"] = spaces.Box(source.low.ravel(), source.high.ravel(), dtype=source.dtype)
        kept["state"] = space["state"]
        self.observation_space = spaces.Dict(kept)

    def observation(self, observation: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        return match_observation(observation, self.observation_space)
