"""The route-offset head: it steers by pure pursuit towards an offset from the route, the offset is
what a behaviour-cloning fit learns, and the policy survives saving and pickling."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from negobs_gym.envs.observation import state_fields
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import STEERING, SteeringHeadConfig, TrainConfig, WarmStartConfig
from negobs_gym.policies.pretrain import warm_start
from negobs_gym.policies.route_offset import RouteOffsetPolicy, pursuit_steering, route_columns
from negobs_gym.policies.training import _new_model, _vec_env, training_spec

ENV = "negobs_gym/OffroadNav-v1"
ORACLE = ("observation.source=oracle",)


def _state_fields() -> tuple[str, ...]:
    return state_fields(training_spec(TrainConfig(env=ENV, overrides=ORACLE)).observation)


def _model(route_offset_m: float = 3.0):
    config = TrainConfig(
        env=ENV, overrides=ORACLE, n_steps=64, head=SteeringHeadConfig(route_offset_m=route_offset_m)
    )
    venv = _vec_env(config)
    try:
        return _new_model(config, venv, (2, 36, 16), _state_fields())
    finally:
        venv.close()


def test_pursuit_steers_towards_the_shifted_route_point_as_the_pure_pursuit_driver_does() -> None:
    straight = torch.tensor([[0.0, 5.0, 0.0, 10.0]] * 3)
    steering = pursuit_steering(straight, torch.tensor([0.0, 1.0, -1.0]))
    assert steering[0] == 0 and steering[1] > 0 and steering[2] == -steering[1]  # + left
    # the driver's law: curvature 2 x_left / L^2, steering atan(wheelbase x curvature) / 35 degrees
    expected = np.arctan(2.8 * 2 * 1.0 / 26.0) / np.radians(35.0)
    assert float(steering[1]) == pytest.approx(expected, rel=1e-6)
    # on a route that bends right, the offset is taken across the route's own direction
    bend = torch.tensor([[1.0, 5.0, 4.0, 9.0]])
    left_of_bend = torch.tensor([1.0, 5.0]) + 2.0 * torch.tensor([-4.0, 3.0]) / 5.0
    direct = torch.atan(2.8 * 2 * -left_of_bend[0] / (left_of_bend**2).sum()) / np.radians(35.0)
    torch.testing.assert_close(pursuit_steering(bend, torch.tensor([2.0]))[0], direct)
    # the mirror image steers the other way; the route's end (both points on it) stays finite
    mirrored = bend * torch.tensor([-1.0, 1.0, -1.0, 1.0])
    torch.testing.assert_close(
        pursuit_steering(mirrored, torch.tensor([-2.0])), -pursuit_steering(bend, torch.tensor([2.0]))
    )
    assert torch.isfinite(pursuit_steering(torch.zeros(1, 4), torch.tensor([3.0]))).all()


def test_the_driven_steering_is_pure_pursuit_towards_the_policys_offset(demos) -> None:
    model = _model()
    policy = model.policy
    assert isinstance(policy, RouteOffsetPolicy)
    obs, _ = policy.obs_to_tensor({key: value[:20] for key, value in demos.observations.items()})
    with torch.no_grad():
        policy.action_net.bias[STEERING] = 0.5
        offset = policy.offset_m(obs)
        mean = policy.get_distribution(obs).distribution.mean
    route = obs["state"][:, list(route_columns(_state_fields(), 5.0))]
    assert torch.all(offset.abs() <= 3.0) and offset.mean() > 1.0  # tanh(0.5) x 3 m, to the left
    torch.testing.assert_close(mean[:, STEERING], pursuit_steering(route, offset))
    driven = model.predict(
        {key: value[:20] for key, value in demos.observations.items()}, deterministic=True
    )[0]
    np.testing.assert_allclose(driven[:, STEERING], np.clip(mean[:, STEERING].numpy(), -1, 1), atol=1e-6)


def test_a_clone_learns_the_offset_that_gives_the_demonstrators_steering(demos) -> None:
    model = _model()
    route = torch.as_tensor(demos.observations["state"][:, list(route_columns(_state_fields(), 5.0))])
    labels = demos.actions.copy()
    labels[:, STEERING] = pursuit_steering(route, torch.full((len(labels),), -1.5)).numpy()  # 1.5 m right
    fit = warm_start(model, replace(demos, actions=labels), WarmStartConfig(steps=1, epochs=30), seed=0)
    assert fit.losses[-1] < 0.2 * fit.losses[0]
    obs, _ = model.policy.obs_to_tensor(demos.observations)
    with torch.no_grad():
        offset = model.policy.offset_m(obs)
    assert offset.mean().item() == pytest.approx(-1.5, abs=0.3)


def test_a_route_offset_policy_survives_saving_and_pickling(demos, reloaded) -> None:
    model = _model()
    with torch.no_grad():
        model.policy.action_net.bias[STEERING] = -0.4
    policy = reloaded(model, {key: value[:10] for key, value in demos.observations.items()})
    assert isinstance(policy, RouteOffsetPolicy) and policy.head.route_offset_m == 3.0


def test_bad_route_offset_heads_are_refused() -> None:
    for bad in ({"route_offset_m": -1.0}, {"route_offset_m": float("nan")}, {"route_point_m": 0.0}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            SteeringHeadConfig(**bad)
    with pytest.raises(ConfigError, match="route_offset_m"):
        SteeringHeadConfig(modes=2, route_offset_m=3.0)
    with pytest.raises(ConfigError, match="PPO only"):
        TrainConfig(algo="SAC", head=SteeringHeadConfig(route_offset_m=3.0))
    with pytest.raises(ConfigError, match="init_model"):
        TrainConfig(init_model="bc_offroad_nav_v2_detector", head=SteeringHeadConfig(route_offset_m=3.0))
    fields = _state_fields()
    for point in (15.0, 7.0):  # the last point (no direction beyond it), and none at all
        with pytest.raises(ConfigError, match=r"head\.route_point_m.*\[5\.0, 10\.0, 15\.0\]"):
            route_columns(fields, point)
    with pytest.raises(ConfigError, match="route_offset_m > 0"):
        RouteOffsetPolicy(None, None, None, head=SteeringHeadConfig(), state_columns=(5, 6, 7, 8))
