"""The steering-candidates head: it drives its best-scored candidate, keeps two sides apart in a
behaviour-cloning fit where a single mean averages them, and survives saving and pickling."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import (
    STEERING,
    SteeringHeadConfig,
    TrainConfig,
    WarmStartConfig,
    steering_head,
)
from negobs_gym.policies.modes import SteeringModesPolicy
from negobs_gym.policies.pretrain import warm_start
from negobs_gym.policies.training import _new_model, _vec_env

ENV = "negobs_gym/OffroadNav-v1"
ORACLE = ("observation.source=oracle",)


def _model(modes: int, bin_edges: tuple[float, ...] = ()):
    head = SteeringHeadConfig(modes=modes, bin_edges=bin_edges)
    config = TrainConfig(env=ENV, overrides=ORACLE, n_steps=64, head=head)
    venv = _vec_env(config)
    try:
        return _new_model(config, venv, (2, 36, 16))
    finally:
        venv.close()


def _two_sides(demos, steering: float = 0.7):
    """Every observation twice, once labelled a pass to the left and once to the right."""
    left, right = demos.actions.copy(), demos.actions.copy()
    left[:, STEERING], right[:, STEERING] = steering, -steering
    return replace(demos, actions=left) + replace(demos, actions=right)


def test_the_action_is_the_best_scored_candidate(demos) -> None:
    model = _model(3)
    policy = model.policy
    assert isinstance(policy, SteeringModesPolicy)
    obs, _ = policy.obs_to_tensor({key: value[:20] for key, value in demos.observations.items()})
    with torch.no_grad():
        policy.action_net.bias[:3] = torch.tensor([0.0, 0.0, 5.0])  # the third candidate scores best
        scores, steering, others = policy.candidates(obs)
        mean = policy.get_distribution(obs).distribution.mean
    assert scores.shape == steering.shape == (20, 3) and others.shape == (20, 1)
    assert (scores.argmax(dim=1) == 2).all()
    torch.testing.assert_close(mean[:, STEERING], steering[:, 2])
    torch.testing.assert_close(mean[:, 1 - STEERING], others[:, 0])
    # the candidates start spread over both sides, so that the fit can tell them apart
    assert steering[:, 0].mean() < -0.3 and steering[:, 2].mean() > 0.3


def test_candidates_keep_two_sides_apart_where_one_mean_averages_them(demos) -> None:
    data = _two_sides(demos)
    fitted = {}
    for modes in (1, 2):
        model = _model(modes)
        warm_start(model, data, WarmStartConfig(steps=1, epochs=30), seed=0)
        fitted[modes] = model.predict(demos.observations, deterministic=True)[0][:, STEERING]
    assert np.abs(fitted[1]).mean() < 0.15  # the mean of +0.7 and -0.7: straight on
    assert np.abs(fitted[2]).min() > 0.5  # one side or the other, each time
    # the throttle is fitted as before
    throttle = model.predict(demos.observations, deterministic=True)[0][:, 1 - STEERING]
    assert np.mean((throttle - demos.actions[:, 1 - STEERING]) ** 2) < 0.05


def test_with_bin_edges_each_candidate_learns_the_labels_of_its_bin(demos) -> None:
    model = _model(3, bin_edges=(-0.3, 0.3))
    warm_start(model, _two_sides(demos), WarmStartConfig(steps=1, epochs=30), seed=0)
    obs, _ = model.policy.obs_to_tensor(demos.observations)
    with torch.no_grad():
        scores, steering, _ = model.policy.candidates(obs)
    # the left bin's candidate learnt -0.7, the right one's +0.7; no label was straight on
    assert steering[:, 0].mean() == pytest.approx(-0.7, abs=0.1)
    assert steering[:, 2].mean() == pytest.approx(0.7, abs=0.1)
    assert (scores.argmax(dim=1) != 1).all()
    driven = model.predict(demos.observations, deterministic=True)[0][:, STEERING]
    assert np.abs(driven).min() > 0.5


def test_the_fit_lowers_the_head_loss_and_scores_the_held_out_drive(demos) -> None:
    model = _model(2)
    demos = replace(demos, episode_ids=np.arange(len(demos.actions)) // 20)  # six short "episodes"
    fit = warm_start(model, demos, WarmStartConfig(steps=1, epochs=20, hold_out_every=3), seed=0)
    assert fit.losses[-1] < 0.5 * fit.losses[0]
    # the held-out loss is the squared error of the driven action, as for a single-mean head
    held = demos.episode_ids % 3 == 2
    obs, _ = model.policy.obs_to_tensor({key: value[held] for key, value in demos.observations.items()})
    with torch.no_grad():
        driven = model.policy.get_distribution(obs).distribution.mean.numpy()
    assert fit.best_epoch == int(np.argmin(fit.held_out_losses))
    squared_error = np.mean((driven - demos.actions[held]) ** 2)
    assert fit.held_out_losses[fit.best_epoch] == pytest.approx(squared_error, rel=1e-4)


def test_a_candidates_policy_survives_saving_and_pickling(demos, reloaded) -> None:
    model = _model(3)
    warm_start(model, _two_sides(demos), WarmStartConfig(steps=1, epochs=3), seed=0)
    policy = reloaded(model, {key: value[:10] for key, value in demos.observations.items()})
    assert isinstance(policy, SteeringModesPolicy) and policy.head.modes == 3


def test_bin_edges_alone_give_their_number_of_candidates() -> None:
    assert steering_head(1, [-0.3, 0.3]) == SteeringHeadConfig(modes=3, bin_edges=(-0.3, 0.3))
    assert steering_head(2) == SteeringHeadConfig(modes=2)
    with pytest.raises(ConfigError, match="bin_edges"):
        steering_head(3, [0.0])  # two candidates' worth of edges for three


def test_bad_heads_are_refused() -> None:
    for bad in ({"modes": 0}, {"modes": 2.5}, {"choice_weight": 0.0}, {"choice_weight": float("nan")}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            SteeringHeadConfig(**bad)
    for bad in (1.0, -0.1, float("inf")):
        with pytest.raises(ConfigError, match="other_modes_weight"):
            SteeringHeadConfig(other_modes_weight=bad)
    for modes, edges in ((3, (0.0,)), (3, (0.3, -0.3)), (2, (1.0,)), (3, (0.1, 0.1)), (2, (float("nan"),))):
        with pytest.raises(ConfigError, match="bin_edges"):
            SteeringHeadConfig(modes=modes, bin_edges=edges)
    with pytest.raises(ConfigError, match="PPO only"):
        TrainConfig(algo="SAC", head=SteeringHeadConfig(modes=2))
    with pytest.raises(ConfigError, match="init_model"):
        TrainConfig(init_model="bc_offroad_nav_v2_detector", head=SteeringHeadConfig(modes=2))
    with pytest.raises(ConfigError, match="modes >= 2"):
        SteeringModesPolicy(None, None, None, head=SteeringHeadConfig(modes=1))
