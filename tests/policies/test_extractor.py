"""GridStateExtractor: shapes, scaling, gradient flow, config checks, and a policy built without warnings."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from gymnasium import spaces

from negobs_gym.errors import ConfigError
from negobs_gym.policies import PolicyObservation
from negobs_gym.policies.config import GridCnnConfig
from negobs_gym.policies.extractor import GridStateExtractor
from tests.policies.test_observation import StandIn, image_warnings


def flat_space(grid: bool = True) -> spaces.Dict:
    return PolicyObservation(StandIn(), grid=grid).observation_space


def test_output_shape_and_state_scaling() -> None:
    space = flat_space()
    extractor = GridStateExtractor(space, grid_shape=(4, 36, 16))
    assert extractor.features_dim == GridCnnConfig().grid_features + 5
    state = torch.as_tensor(np.stack([space["state"].high, space["state"].low, np.zeros(5, np.float32)]))
    out = extractor({"grid": torch.zeros(3, 4 * 36 * 16), "state": state})
    assert out.shape == (3, extractor.features_dim)
    np.testing.assert_allclose(out[:, -5:].detach().numpy(), [[1.0] * 5, [-1.0] * 5, [0.0] * 5])


def test_a_three_d_grid_space_and_state_only() -> None:
    extractor = GridStateExtractor(StandIn().observation_space, config=GridCnnConfig(grid_features=32))
    assert extractor.grid_shape == (4, 36, 16) and extractor.features_dim == 37
    out = extractor({"grid": torch.ones(2, 4, 36, 16), "state": torch.zeros(2, 5)})
    assert out.shape == (2, 37)
    state_only = GridStateExtractor(flat_space(grid=False))
    assert state_only.features_dim == 5 and state_only.cnn is None


def test_a_counting_grid_reaches_the_cnn_scaled_to_one() -> None:
    binary = flat_space()
    counting = spaces.Dict(
        {"grid": spaces.Box(0, 16, binary["grid"].shape, np.uint8), "state": binary["state"]}
    )
    torch.manual_seed(0)
    one = GridStateExtractor(binary, grid_shape=(4, 36, 16))
    other = GridStateExtractor(counting, grid_shape=(4, 36, 16))
    other.load_state_dict(one.state_dict())  # the scale is no weight: models saved before load as they were
    state = torch.zeros(2, 5)
    full = other({"grid": torch.full((2, 4 * 36 * 16), 16.0), "state": state})
    torch.testing.assert_close(full, one({"grid": torch.ones(2, 4 * 36 * 16), "state": state}))


def test_gradient_reaches_every_layer_and_the_grid_matters() -> None:
    torch.manual_seed(0)
    extractor = GridStateExtractor(flat_space(), grid_shape=(4, 36, 16))
    grid = (torch.rand(8, 4 * 36 * 16) < 0.2).float()
    out = extractor({"grid": grid, "state": torch.randn(8, 5)})
    out.pow(2).sum().backward()
    params = dict(extractor.named_parameters())
    assert len(params) == 8  # 3 conv + 1 linear layers, weight and bias each
    for name, p in params.items():
        assert p.grad is not None and torch.count_nonzero(p.grad) > 0, name
    with torch.no_grad():
        empty = extractor({"grid": torch.zeros_like(grid), "state": torch.zeros(8, 5)})
        full = extractor({"grid": grid, "state": torch.zeros(8, 5)})
    assert not torch.allclose(empty[:, :-5], full[:, :-5])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"conv_channels": ()}, "conv_channels"),
        ({"kernel_sizes": (3, 3)}, "kernel_sizes"),
        ({"kernel_sizes": (3, 4, 3)}, "kernel_sizes"),
        ({"strides": (1, 0, 2)}, "strides"),
        ({"grid_features": 0}, "grid_features"),
    ],
)
def test_bad_config_names_its_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        GridCnnConfig(**kwargs)


def test_grid_shape_must_fit_the_flat_grid() -> None:
    with pytest.raises(ConfigError, match="grid_shape"):
        GridStateExtractor(flat_space())
    with pytest.raises(ConfigError, match="grid_shape"):
        GridStateExtractor(flat_space(), grid_shape=(4, 36, 15))


@pytest.mark.parametrize("algo", ["PPO", "SAC"])
def test_building_the_policy_raises_no_image_warning(algo: str) -> None:
    import stable_baselines3

    env = PolicyObservation(StandIn())
    kwargs = {
        "features_extractor_class": GridStateExtractor,
        "features_extractor_kwargs": {"grid_shape": env.grid_shape},
    }
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        extra = (
            {"n_steps": 8, "batch_size": 8} if algo == "PPO" else {"buffer_size": 100, "learning_starts": 0}
        )
        model = getattr(stable_baselines3, algo)(
            "MultiInputPolicy", env, policy_kwargs=kwargs, device="cpu", **extra
        )
        if algo == "PPO":
            model.learn(8)
        model.predict(env.observation_space.sample())
    assert image_warnings(record) == []
    assert isinstance(
        model.policy.features_extractor if algo == "PPO" else model.actor.features_extractor,
        GridStateExtractor,
    )
