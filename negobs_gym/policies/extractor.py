"""A small CNN over the vehicle-centred grid plus the scaled state vector, for SB3's ``MultiInputPolicy``.

Neither paper trains a policy, so nothing here comes from them: the layer sizes are choices,
each with its reason in :class:`~negobs_gym.policies.config.GridCnnConfig`. SB3's
``NatureCNN`` does not fit: its 8 x 8 stride-4 first layer would leave a 16-cell-wide grid 3 cells
wide and skip most 80 cm cells, in which a single pit can be one cell.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import GridCnnConfig

__all__ = ["GridStateExtractor"]


class GridStateExtractor(BaseFeaturesExtractor):
    """Features = [CNN(grid) -> ``grid_features``, state / bound]; the grid part only when present.

    The grid may arrive flat (:class:`~negobs_gym.policies.PolicyObservation`; ``grid_shape``
    gives (channels, rows, cols)) or as a 3-D ``Box``. The state is divided component-wise by the
    largest magnitude its space allows (speed 15 m/s, goal 300 m, ...), so every input lies in
    [-1, 1]; the policy's own MLP follows.

    Args:
        observation_space: ``Dict`` with ``state`` and optionally ``grid``.
        grid_shape: (channels, rows, cols) of a flat ``grid``; taken from a 3-D grid space if None.
        config: The layers (:class:`GridCnnConfig`).
    """

    def __init__(
        self,
        observation_space: spaces.Dict,
        grid_shape: tuple[int, int, int] | None = None,
        config: GridCnnConfig | None = None,
    ) -> None:
        config = config if config is not None else GridCnnConfig()
        if not isinstance(observation_space, spaces.Dict) or "state" not in observation_space.spaces:
            raise ConfigError("observation_space", f"needs a Dict with 'state', got {observation_space}")
        state_space = observation_space["state"]
        grid_space = observation_space.spaces.get("grid")
        shape = _grid_shape(grid_space, grid_shape) if grid_space is not None else None
        n_state = int(np.prod(state_space.shape))
        super().__init__(observation_space, (config.grid_features if shape else 0) + n_state)
        self.config = config
        self.grid_shape = shape
        bound = np.maximum(np.abs(state_space.low), np.abs(state_space.high)).astype(np.float32).ravel()
        if not np.all(np.isfinite(bound)) or np.any(bound <= 0):
            raise ConfigError("observation_space", f"'state' needs finite non-zero bounds, got {state_space}")
        self.register_buffer("state_scale", torch.as_tensor(bound))
        # a counting grid's cells reach downsample**2; the CNN sees every grid in [0, 1]
        self.grid_scale = float(np.max(grid_space.high)) if grid_space is not None else 1.0
        if not (math.isfinite(self.grid_scale) and self.grid_scale > 0):
            raise ConfigError("observation_space", f"'grid' needs a finite bound > 0, got {grid_space}")
        self.cnn: nn.Module | None = None
        if shape is not None:
            layers: list[nn.Module] = []
            in_ch = shape[0]
            for out_ch, k, s in zip(config.conv_channels, config.kernel_sizes, config.strides, strict=True):
                layers += [nn.Conv2d(in_ch, out_ch, k, stride=s, padding=k // 2), nn.ReLU()]
                in_ch = out_ch
            layers.append(nn.Flatten())
            convs = nn.Sequential(*layers)
            with torch.no_grad():
                n_flat = int(convs(torch.zeros(1, *shape)).shape[1])
            self.cnn = nn.Sequential(convs, nn.Linear(n_flat, config.grid_features), nn.ReLU())

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        state = observations["state"].reshape(observations["state"].shape[0], -1) / self.state_scale
        if self.cnn is None:
            return state
        grid = observations["grid"].float().reshape(-1, *self.grid_shape) / self.grid_scale
        return torch.cat([self.cnn(grid), state], dim=1)


def _grid_shape(space: spaces.Space, grid_shape: tuple[int, int, int] | None) -> tuple[int, int, int]:
    """(channels, rows, cols) of the grid: ``grid_shape`` for a flat space, else the space's own."""
    if not isinstance(space, spaces.Box):
        raise ConfigError("observation_space", f"'grid' must be a Box, got {space}")
    if grid_shape is None:
        if len(space.shape) != 3:
            raise ConfigError("grid_shape", f"a flat grid of shape {space.shape} needs grid_shape (C, R, W)")
        return tuple(int(v) for v in space.shape)  # type: ignore[return-value]
    shape = tuple(int(v) for v in grid_shape)
    if len(shape) != 3 or int(np.prod(shape)) != int(np.prod(space.shape)):
        raise ConfigError(
            "grid_shape", f"{grid_shape} does not hold the grid's {int(np.prod(space.shape))} cells"
        )
    return shape  # type: ignore[return-value]
