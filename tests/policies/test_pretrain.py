"""Warm start: demonstrations of a scripted driver and behaviour cloning into a PPO policy."""

from __future__ import annotations

import copy
import functools
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from negobs_gym.drivers import make_driver
from negobs_gym.drivers.grid_planner import GridPlannerDriver
from negobs_gym.drivers.pure_pursuit import PurePursuitDriver
from negobs_gym.drivers.track_planner import TrackPlannerConfig, TrackPlannerDriver
from negobs_gym.errors import ConfigError
from negobs_gym.policies.config import TrainConfig, WarmStartConfig
from negobs_gym.policies.pretrain import (
    DEMO_SEED_OFFSET,
    DemonstrationPool,
    Demonstrations,
    PolicyActor,
    collect_demonstrations,
    warm_start,
)
from negobs_gym.policies.training import _check_layout, _new_model, _vec_env, make_training_env

ENV = "negobs_gym/OffroadNav-v1"
ORACLE = ("observation.source=oracle",)
DEMO_STEPS, DEMO_SEED = 160, 7  # the demos fixture's (conftest.py)


def test_demonstrations_label_the_drivers_clean_actions(demos) -> None:
    assert demos.actions.shape == (160, 2) and demos.episodes >= 1
    assert demos.episode_ids[0] == 0 and demos.episode_ids[-1] == demos.episodes - 1
    assert (np.diff(demos.episode_ids) >= 0).all()
    assert demos.observations["grid"].shape == (160, 2 * 36 * 16)
    assert demos.observations["state"].shape == (160, 11)
    # replay the first episode: the labels are the driver's actions on the recorded observations
    env = make_training_env(ENV, ORACLE)
    obs, info = env.reset(seed=7 + DEMO_SEED_OFFSET)
    driver = PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m)
    np.testing.assert_array_equal(demos.observations["state"][0], obs["state"])
    np.testing.assert_array_equal(demos.actions[0], driver.act(obs, info))
    env.close()
    # the executed actions carried noise: the demonstrated speeds are not one deterministic ramp
    assert np.std(np.diff(demos.observations["state"][:40, 0])) > 0


def test_behaviour_cloning_fits_the_driver_and_sets_the_exploration(demos) -> None:
    config = TrainConfig(env=ENV, overrides=ORACLE, n_steps=64)
    venv = _vec_env(config)
    model = _new_model(config, venv, (2, 36, 16))
    venv.close()
    before, _ = model.predict(demos.observations, deterministic=True)
    ws = WarmStartConfig(steps=160, epochs=30, action_std=0.25)
    fit = warm_start(model, demos, ws, seed=0)
    after, _ = model.predict(demos.observations, deterministic=True)
    error_before = np.mean((before - demos.actions) ** 2)
    error_after = np.mean((after - demos.actions) ** 2)
    assert fit.losses[-1] < 0.5 * fit.losses[0]
    assert fit.held_out_losses == [] and fit.best_epoch == 29
    assert error_after < 0.25 * error_before
    np.testing.assert_allclose(model.policy.log_std.detach().numpy(), np.log(0.25), rtol=1e-6)


def test_warm_start_is_ppo_only_and_validated() -> None:
    with pytest.raises(ConfigError, match="warm_start"):
        TrainConfig(algo="SAC", warm_start=WarmStartConfig(steps=100))
    with pytest.raises(ConfigError, match="action_std"):
        WarmStartConfig(action_std=0.0)
    with pytest.raises(ConfigError, match="steps"):
        WarmStartConfig(steps=-1)
    with pytest.raises(ConfigError, match="driver"):
        WarmStartConfig(driver="reckless")
    with pytest.raises(ConfigError, match="planner_sight_m"):
        WarmStartConfig(planner_sight_m=float("nan"))
    with pytest.raises(ConfigError, match="hold_out_every"):
        WarmStartConfig(hold_out_every=1)
    with pytest.raises(ConfigError, match="mirror"):
        WarmStartConfig(mirror="yes")


def test_track_planner_demonstrations_pass_the_first_obstacle_on_offroad_nav_v2() -> None:
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    try:
        demos = collect_demonstrations(env, 120, noise_std=0.0, seed=0, driver="track_planner")
        obs, info = env.reset(seed=DEMO_SEED_OFFSET)
        first = TrackPlannerDriver(env.unwrapped.terrain).act(obs, info)
    finally:
        env.close()
    np.testing.assert_array_equal(demos.actions[0], first)
    # the first obstacle of every winding course is at ~25 m, where the centre-line driver enters
    # it (tests/drivers/test_track_planner.py): 120 steps of the planner drive past it in one episode
    assert demos.episodes == 1
    assert np.abs(demos.actions[:, 1]).max() > 0.1  # it steered around


def test_grid_planner_demonstrations_label_with_the_grid_the_policy_sees() -> None:
    # the training env hands the grid flat (PolicyObservation); the planner folds it back
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    try:
        demos = collect_demonstrations(env, 120, noise_std=0.0, seed=0, driver="grid_planner")
        obs, info = env.reset(seed=DEMO_SEED_OFFSET)
        scene = env.unwrapped.scenario
        first = GridPlannerDriver(env.unwrapped.terrain, scene.observation).act(obs, info)
    finally:
        env.close()
    assert obs["grid"].ndim == 1
    np.testing.assert_array_equal(demos.actions[0], first)
    assert demos.episodes == 1
    assert np.abs(demos.actions[:, 1]).max() > 0.1  # it steered around the first obstacle


def _drive_first_episode(env: Any, driver: Any, steps: int) -> np.ndarray:
    """``driver``'s actions over ``steps`` steps of the first demonstration episode (seed 0's),
    each one executed: the labels a noiseless collection gives."""
    obs, info = env.reset(seed=DEMO_SEED_OFFSET)
    labels = []
    for _ in range(steps):
        labels.append(driver.act(obs, info))
        obs, _, _, _, info = env.step(labels[-1])
    return np.stack(labels)


def test_driver_settings_configure_the_demonstrator() -> None:
    # the grid planner's heading lattice, slower than its own cruise speed
    heading = {"planner": {"bend_steps": 1, "pursuit": {"target_speed_mps": 3.0}}}
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    try:
        demos = collect_demonstrations(env, 60, 0.0, 0, "grid_planner", driver_settings=heading)
        plain = collect_demonstrations(env, 60, 0.0, 0, "grid_planner")
        env.reset(seed=DEMO_SEED_OFFSET)  # the first episode's course, for the driver
        scene, terrain = env.unwrapped.scenario, env.unwrapped.terrain
        driver = make_driver("grid_planner", terrain, observation=scene.observation, settings=heading)
        labels = _drive_first_episode(env, driver, 60)
    finally:
        env.close()
    assert driver.config.planner.bend_steps == 1
    np.testing.assert_array_equal(demos.actions, labels)
    assert demos.actions[-20:, 0].mean() < plain.actions[-20:, 0].mean()  # it eased off earlier


def test_driver_settings_are_checked_when_the_config_is_built() -> None:
    ws = WarmStartConfig(driver="grid_planner", driver_settings={"planner": {"bend_steps": 2}})
    assert ws.driver_settings["planner"]["bend_steps"] == 2
    with pytest.raises(ConfigError, match=r"driver_settings.*bend_stepz"):
        WarmStartConfig(driver="grid_planner", driver_settings={"planner": {"bend_stepz": 1}})
    with pytest.raises(ConfigError, match="driver_settings"):
        WarmStartConfig(driver="grid_planner", driver_settings={"planner": {"bend_steps": -1}})
    with pytest.raises(ConfigError, match="driver_settings"):
        WarmStartConfig(driver="pure_pursuit", driver_settings={"planner": {"bend_steps": 1}})


def test_dagger_rollouts_execute_the_policy_and_label_with_the_driver() -> None:
    full_throttle = np.array([1.0, 0.0], dtype=np.float32)
    env = make_training_env(ENV, ORACLE)
    try:
        demos = collect_demonstrations(env, 30, 0.0, 3, policy=lambda obs: full_throttle, first_episode=5)
        # replay: the same course (episode 5), the policy's action executed, the driver's as labels
        obs, info = env.reset(seed=3 + DEMO_SEED_OFFSET + 5)
        driver = PurePursuitDriver(env.unwrapped.terrain.track.centreline_xy_m)
        labels = []
        for _ in range(30):
            labels.append(driver.act(obs, info))
            obs, _, _, _, info = env.step(full_throttle)
    finally:
        env.close()
    np.testing.assert_array_equal(demos.actions, np.stack(labels))
    np.testing.assert_array_equal(demos.episode_ids, 5)  # one episode, numbered from first_episode
    assert not np.allclose(demos.actions[:, 0], 1.0)  # the driver would have eased off at cruise speed
    both = demos + demos
    assert both.actions.shape == (60, 2) and both.episodes == 2
    np.testing.assert_array_equal(both.observations["grid"][30:], demos.observations["grid"])


def test_a_sight_limited_planner_labels_what_it_sees() -> None:
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    try:
        full = collect_demonstrations(env, 80, noise_std=0.0, seed=0, driver="track_planner")
        near = collect_demonstrations(env, 80, 0.0, 0, "track_planner", planner_sight_m=14.0)
        env.reset(seed=DEMO_SEED_OFFSET)
        driver = TrackPlannerDriver(env.unwrapped.terrain, TrackPlannerConfig(sight_m=14.0))
        labels = _drive_first_episode(env, driver, 80)
    finally:
        env.close()
    np.testing.assert_array_equal(near.actions, labels)
    assert driver.replans >= 1  # the first obstacle came into sight on the way
    assert not np.array_equal(near.actions, full.actions)  # the whole course's path starts earlier


def test_each_episode_depends_on_its_number_alone(demos) -> None:
    """The noise of episode k comes from k's own generator: collecting from episode 1 on gives the
    same steps as episode 1 of a collection from episode 0 (what lets workers share episodes)."""
    assert demos.episodes >= 2
    env = make_training_env(ENV, ORACLE)
    try:
        later = collect_demonstrations(env, 40, noise_std=0.3, seed=7, first_episode=1)
    finally:
        env.close()
    first = np.flatnonzero(demos.episode_ids == 1)[:40]
    np.testing.assert_array_equal(later.actions, demos.actions[first])
    np.testing.assert_array_equal(later.observations["grid"], demos.observations["grid"][first])
    np.testing.assert_array_equal(later.episode_ids, 1)


def _env_noting_its_life(marks: Path) -> Any:
    """An OffroadTrack-v0 env that appends ``made`` to ``marks`` when it is made, ``closed`` when closed."""
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    with marks.open("a") as fh:
        fh.write("made\n")
    close = env.close

    def close_and_note() -> None:
        close()
        with marks.open("a") as fh:
            fh.write("closed\n")

    env.close = close_and_note
    return env


# slow (end to end): two workers' demonstrations against one process's; the collection itself is
# checked by the default tests
@pytest.mark.slow
def test_two_worker_processes_collect_the_steps_one_process_does(tmp_path: Path) -> None:
    """DAgger on OffroadTrack-v0 with an untrained policy: short episodes, so several run at once.
    One pool serves two rounds, each driven by its own weights, as one process collects them."""
    marks = tmp_path / "lives.txt"
    factory = functools.partial(_env_noting_its_life, marks)
    learner = PolicyActor(_fresh_model().policy)
    refitted = PolicyActor(copy.deepcopy(learner.policy))  # other weights: the next round's policy
    with torch.no_grad():
        for weight in refitted.policy.action_net.parameters():
            weight.neg_()  # the opposite action mean
    env = make_training_env("negobs_gym/OffroadTrack-v0", ORACLE)
    try:
        one = collect_demonstrations(env, 150, 0.3, 3, policy=learner, first_episode=2)
        later = collect_demonstrations(env, 30, 0.3, 3, policy=refitted, first_episode=2)
        with DemonstrationPool(2, factory) as pool:
            two = collect_demonstrations(env, 150, 0.3, 3, policy=learner, first_episode=2, pool=pool)
            again = collect_demonstrations(env, 30, 0.3, 3, policy=refitted, first_episode=2, pool=pool)
    finally:
        env.close()
    # the two processes started once for both rounds, and each closed its env
    assert marks.read_text().splitlines() == ["made", "made", "closed", "closed"]
    assert one.episodes >= 3 and two.episodes == one.episodes
    for near, far in ((one, two), (later, again)):
        np.testing.assert_array_equal(far.episode_ids, near.episode_ids)
        np.testing.assert_array_equal(far.actions, near.actions)
        for key, value in near.observations.items():
            np.testing.assert_array_equal(far.observations[key], value)
    # the second round's weights drove it: the same courses, other states
    assert not np.array_equal(later.observations["state"], one.observations["state"][:30])
    with pytest.raises(ConfigError, match="workers"):
        DemonstrationPool(0, factory)
    with pytest.raises(ConfigError, match="workers"):
        WarmStartConfig(steps=10, workers=0)


def _fresh_model():
    config = TrainConfig(env=ENV, overrides=ORACLE, n_steps=64)
    venv = _vec_env(config)
    model = _new_model(config, venv, (2, 36, 16))
    venv.close()
    return model


def test_mirrored_demonstrations_flip_the_grid_and_the_lateral_values(demos) -> None:
    mirror = demos.mirrored()
    grid = demos.observations["grid"].reshape(-1, 2, 36, 16)
    assert grid.any()  # the demonstrations saw obstacles: the flip is not of empty grids
    np.testing.assert_array_equal(mirror.observations["grid"].reshape(-1, 2, 36, 16), grid[..., ::-1])
    state = demos.observations["state"]
    np.testing.assert_array_equal(mirror.observations["state"], state * demos.state_signs)
    np.testing.assert_array_equal(mirror.actions[:, 0], demos.actions[:, 0])
    np.testing.assert_array_equal(mirror.actions[:, 1], -demos.actions[:, 1])
    assert mirror.episodes == 0 and np.array_equal(mirror.episode_ids, demos.episode_ids)
    twice = mirror.mirrored()
    for key, value in demos.observations.items():
        np.testing.assert_array_equal(twice.observations[key], value)
    np.testing.assert_array_equal(twice.actions, demos.actions)


def _mirror_gap(model, demos) -> float:
    """How far the policy is from acting as the mirror image of itself on mirrored states."""
    seen, _ = model.predict(demos.observations, deterministic=True)
    mirrored, _ = model.predict(demos.mirrored().observations, deterministic=True)
    return float(np.abs(mirrored[:, 1] + seen[:, 1]).mean())


def test_a_mirrored_fit_steers_symmetrically(demos) -> None:
    """The pure-pursuit demonstrations on one course turn mostly one way; fitted with their mirror
    images, the policy steers the other way on the mirrored states."""
    plain, mirrored = _fresh_model(), _fresh_model()
    warm_start(plain, demos, WarmStartConfig(steps=160, epochs=30), seed=0)
    warm_start(mirrored, demos, WarmStartConfig(steps=160, epochs=30, mirror=True), seed=0)
    assert _mirror_gap(mirrored, demos) < 0.5 * _mirror_gap(plain, demos)


def test_the_hold_out_is_left_out_of_the_fit_and_picks_the_best_epoch(demos) -> None:
    split = replace(demos, episode_ids=np.arange(160) // 20)  # 8 "episodes" of 20 steps
    kept = ~np.isin(split.episode_ids, (2, 5))  # every 3rd: ids 2 and 5
    fitted_only = replace(
        split,
        observations={k: v[kept] for k, v in split.observations.items()},
        actions=split.actions[kept],
        episode_ids=split.episode_ids[kept],
    )
    torch.manual_seed(0)
    a = _fresh_model()
    torch.manual_seed(0)
    b = _fresh_model()
    held = warm_start(a, split, WarmStartConfig(steps=160, epochs=12, hold_out_every=3), seed=0)
    plain = warm_start(b, fitted_only, WarmStartConfig(steps=160, epochs=12), seed=0)
    # the same minibatches of the same steps: the held-out ones never entered the fit
    np.testing.assert_allclose(held.losses, plain.losses, rtol=1e-5)
    assert len(held.held_out_losses) == 12
    assert held.best_epoch == int(np.argmin(held.held_out_losses))
    # the policy kept that epoch's weights: its held-out error is the lowest one recorded
    predicted, _ = a.predict({k: v[~kept] for k, v in split.observations.items()}, deterministic=True)
    clipped = np.clip(split.actions[~kept], -1, 1)
    assert np.mean((predicted - clipped) ** 2) <= min(held.held_out_losses) + 1e-4
    one_episode = replace(demos, episode_ids=np.zeros(160, dtype=np.int64))
    with pytest.raises(ConfigError, match="hold_out_every"):
        warm_start(_fresh_model(), one_episode, WarmStartConfig(steps=160, hold_out_every=2), seed=0)


def test_demonstrations_survive_a_round_trip_to_disk(demos, tmp_path) -> None:
    path = demos.save(tmp_path / "demos.npz")
    loaded = Demonstrations.load(path)
    assert loaded.observations.keys() == demos.observations.keys()
    for key, value in demos.observations.items():
        assert loaded.observations[key].dtype == value.dtype
        np.testing.assert_array_equal(loaded.observations[key], value)
    np.testing.assert_array_equal(loaded.actions, demos.actions)
    np.testing.assert_array_equal(loaded.episode_ids, demos.episode_ids)
    np.testing.assert_array_equal(loaded.state_signs, demos.state_signs)
    assert loaded.episodes == demos.episodes and loaded.grid_shape == demos.grid_shape
    assert loaded.grid_max == demos.grid_max == 1
    assert [p.name for p in tmp_path.iterdir()] == ["demos.npz"]  # no temp file left behind
    counting = replace(demos, grid_max=16)  # a pooling="count" env's grid
    assert Demonstrations.load(counting.save(tmp_path / "counting.npz")).grid_max == 16
    with pytest.raises(ConfigError, match=r"^demonstrations: different observation layouts") as joined:
        demos + counting
    assert joined.value.field == "demonstrations" and isinstance(joined.value, ValueError)
    env = make_training_env(ENV, ORACLE)
    try:
        _check_layout(demos, env, "binary.npz")
        with pytest.raises(ConfigError, match="values up to 16"):
            _check_layout(counting, env, "counting.npz")
    finally:
        env.close()
    (tmp_path / "counting.npz").unlink()
    with pytest.raises(ConfigError, match="cannot read"):
        Demonstrations.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", actions=demos.actions)
    with pytest.raises(ConfigError, match="not a demonstrations file"):
        Demonstrations.load(tmp_path / "other.npz")


def test_weight_decay_shrinks_the_fitted_weights(demos) -> None:
    def fitted_norm(weight_decay: float) -> float:
        torch.manual_seed(0)
        model = _fresh_model()
        warm_start(
            model,
            demos,
            WarmStartConfig(steps=160, epochs=10, batch_size=16, weight_decay=weight_decay),
            seed=0,
        )
        actor = [p for n, p in model.policy.named_parameters() if "action_net" in n or "policy_net" in n]
        return float(sum((p.detach() ** 2).sum() for p in actor))

    assert fitted_norm(5.0) < 0.8 * fitted_norm(0.0)
    with pytest.raises(ConfigError, match="weight_decay"):
        WarmStartConfig(weight_decay=-0.1)


def test_strong_steering_steps_enter_the_fit_as_often_as_asked(demos) -> None:
    """Repeating the passes is a fit on the demonstrations with those steps copied: with one
    minibatch per epoch the order cannot tell them apart."""
    strong = np.flatnonzero(np.abs(demos.actions[:, 1]) > 0.1)
    assert 0 < len(strong) < len(demos.actions)
    copies = replace(
        demos,
        observations={k: v[strong] for k, v in demos.observations.items()},
        actions=demos.actions[strong],
        episode_ids=demos.episode_ids[strong],
        episodes=0,
    )
    whole_batch = {"steps": 160, "epochs": 6, "batch_size": 1024}
    torch.manual_seed(0)
    repeated = _fresh_model()
    torch.manual_seed(0)
    copied = _fresh_model()
    fit = warm_start(
        repeated, demos, WarmStartConfig(**whole_batch, strong_steer=0.1, strong_steer_repeats=3), seed=0
    )
    reference = warm_start(copied, demos + copies + copies, WarmStartConfig(**whole_batch), seed=0)
    np.testing.assert_allclose(fit.losses, reference.losses, rtol=1e-4)
    a, _ = repeated.predict(demos.observations, deterministic=True)
    b, _ = copied.predict(demos.observations, deterministic=True)
    np.testing.assert_allclose(a, b, atol=1e-4)
    torch.manual_seed(0)
    plain = _fresh_model()
    plain_fit = warm_start(plain, demos, WarmStartConfig(**whole_batch), seed=0)
    assert plain_fit.losses != fit.losses  # the repeats changed the fit
    with pytest.raises(ConfigError, match="strong_steer_repeats"):
        WarmStartConfig(strong_steer_repeats=0)
    with pytest.raises(ConfigError, match="strong_steer"):
        WarmStartConfig(strong_steer=float("inf"))
