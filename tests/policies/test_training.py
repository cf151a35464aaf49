"""train(): SAC on the state alone from a scenario TOML, resume, and what a resumed run must match;
a run's env is its scenario with the overrides applied, and old train.json records still resume."""

from __future__ import annotations

import dataclasses
import json
import shutil
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.envs import make_env, source_overrides
from negobs_gym.errors import ConfigError
from negobs_gym.policies.callbacks import latest_checkpoint
from negobs_gym.policies.config import TrainConfig, WarmStartConfig
from negobs_gym.policies.training import (
    filter_setting,
    make_training_env,
    run_filter,
    train,
    training_overrides,
    training_spec,
)
from negobs_gym.safety import BrakingSafetyFilter
from negobs_gym.spec import Range, load_scenario, spec_from_toml
from negobs_gym.spec.scenario import SCENE_FILTER

ORACLE = ("observation.source=oracle",)


def test_sac_state_only_from_a_toml_spec_resumes(tmp_path: Path) -> None:
    spec = tmp_path / "my_braking.toml"
    shutil.copy(resources.files("negobs_gym.spec").joinpath("scenes/braking_v1.toml"), spec)
    config = TrainConfig(
        env=str(spec),
        algo="SAC",
        overrides=ORACLE,
        grid_input=False,
        steps=120,
        batch_size=32,
        eval_every=100,
        eval_episodes=1,
        checkpoint_every=50,
        progress=False,
    )
    out = tmp_path / "run"
    first = train(config, out)
    assert first.steps == 120 and first.model_path.is_file()
    assert latest_checkpoint(out / "checkpoints").name == "model_120.zip"
    rows = first.eval_csv.read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["100", "120"]

    # an eval.csv written before the off_track column: its rows are kept with that cell empty
    table = [line.split(",") for line in rows]
    drop = table[0].index("off_track")
    first.eval_csv.write_text("\n".join(",".join(r[:drop] + r[drop + 1 :]) for r in table) + "\n")
    # a train.json of the version that copied source and filter into the config: translated
    record = json.loads((out / "train.json").read_text())
    assert record["config"]["overrides"] == list(ORACLE) and record["config"]["grid_input"] is False
    for key in ("overrides", "grid_input"):
        del record["config"][key]
    record["config"].update(source="state", filter=False, stop_for_positive=False)
    (out / "train.json").write_text(json.dumps(record))
    second = train(dataclasses.replace(config, steps=180), out, resume=True)
    assert second.steps == 180
    rows = second.eval_csv.read_text().splitlines()
    assert [r.split(",")[0] for r in rows[1:]] == ["100", "120", "180"]  # earlier rows kept
    assert [r.split(",")[drop] for r in rows[1:]] == ["", "", "0"]
    record = json.loads((out / "train.json").read_text())
    assert record["session_start_step"] == 120 and record["steps"] == 180
    assert (out / "logs" / "120" / "progress.csv").is_file()

    from stable_baselines3 import SAC

    model = SAC.load(second.model_path, device="cpu")
    assert list(model.observation_space.spaces) == ["state"] and model.num_timesteps == 180

    with pytest.raises(ConfigError, match="grid_input: False there, True now"):
        train(dataclasses.replace(config, steps=240, grid_input=True), out, resume=True)
    detector = ("observation.source=detector",)
    with pytest.raises(ConfigError, match=r"observation\.source: 'oracle' there, 'detector' now"):
        train(dataclasses.replace(config, steps=240, overrides=detector), out, resume=True)
    with pytest.raises(ConfigError, match=r"run\.filter: False there, True now"):
        train(
            dataclasses.replace(config, steps=240, overrides=(*ORACLE, "run.filter=true")), out, resume=True
        )
    # the same scenario spelt otherwise resumes: the spec's own grid source is the detectors'
    assert spec_from_toml(spec.read_text()).observation.source == "detector"
    with pytest.raises(ConfigError, match="nothing to train"):
        train(dataclasses.replace(config, steps=150), out, resume=True)


#: A short PPO run on the oracle grid: 64-step rollouts, one evaluation episode at the end.
SHORT_PPO = TrainConfig(
    env="negobs_gym/Braking-v1",
    overrides=ORACLE,
    steps=128,
    n_steps=64,
    eval_every=0,
    eval_episodes=1,
    checkpoint_every=0,
    progress=False,
)


def policy_weights(model_path: Path):
    """All policy parameters of a saved PPO model, as one flat tensor."""
    import torch
    from stable_baselines3 import PPO

    return torch.cat([p.flatten() for p in PPO.load(model_path, device="cpu").policy.parameters()])


def test_same_seed_same_model_and_evaluation(tmp_path: Path) -> None:
    import torch

    runs = [train(SHORT_PPO, tmp_path / str(k)) for k in range(2)]
    assert torch.equal(policy_weights(runs[0].model_path), policy_weights(runs[1].model_path))
    rows = [r.eval_csv.read_text().splitlines()[1].rsplit(",", 1)[0] for r in runs]  # all but wall_s
    assert rows[0] == rows[1]


def test_the_record_names_the_code_the_run_started_on(tmp_path: Path, monkeypatch) -> None:
    """A checkout that moves on during a long run does not relabel the policy's code."""
    from negobs_gym.core import provenance

    versions = iter(f"0.1.0+commit{k}" for k in range(100))
    monkeypatch.setattr(provenance, "code_version", lambda: next(versions))
    train(dataclasses.replace(SHORT_PPO, steps=64), tmp_path)
    assert json.loads((tmp_path / "train.json").read_text())["code"] == "0.1.0+commit0"


# slow (end to end): two trainings from a trained model; a training run and its record are checked
# by the other default tests
@pytest.mark.slow
def test_init_fine_tunes_a_trained_model_and_a_critic_warmup_moves_only_its_value_function(
    tmp_path: Path,
) -> None:
    """One 64-step :data:`SHORT_PPO` run (one rollout, one update), trained once: the model both
    halves start from, which they only read."""
    first = train(dataclasses.replace(SHORT_PPO, steps=64), tmp_path / "short_ppo_64")
    assert first.steps == 64 and first.model_path.is_file()
    _check_init_fine_tunes_a_trained_model_on_another_source(tmp_path, first)
    _check_critic_warmup_moves_only_the_value_function_then_everything(tmp_path, first)


def _check_init_fine_tunes_a_trained_model_on_another_source(tmp_path: Path, first) -> None:
    import torch
    from stable_baselines3 import PPO

    base = dataclasses.replace(SHORT_PPO, steps=64)
    tuned = dataclasses.replace(
        base, grid_input=False, init_model=str(first.model_path), learning_rate=1e-3, eval_seed=7
    )
    with pytest.raises(ConfigError, match="init_model"):  # the state-only policy has no grid input
        train(tuned, tmp_path / "bad")

    detector = ("observation.source=detector",)
    tuned = dataclasses.replace(tuned, grid_input=True, overrides=detector, steps=32, n_steps=32)
    second = train(tuned, tmp_path / "detector")
    rows = second.eval_csv.read_text().splitlines()[1:]
    assert [r.split(",")[0] for r in rows] == ["0", "32"]  # the init model's row first; steps from 0
    model = PPO.load(second.model_path, device="cpu")
    assert model.num_timesteps == 32 and model.n_steps == 32 and model.learning_rate == 1e-3
    assert not torch.equal(policy_weights(first.model_path), policy_weights(second.model_path))  # trained
    record = json.loads((tmp_path / "detector" / "train.json").read_text())
    assert record["config"]["init_model"] == str(first.model_path)
    assert record["config"]["eval_seed"] == 7
    with pytest.raises(ConfigError, match="init_model"):
        train(dataclasses.replace(base, init_model="no_such_policy"), tmp_path / "missing")
    from stable_baselines3 import SAC

    env = make_training_env(base.env, base.overrides)
    SAC("MultiInputPolicy", env, buffer_size=10, device="cpu").save(tmp_path / "sac.zip")
    env.close()
    with pytest.raises(ConfigError, match="init_model"):  # a SAC model as the start of a PPO run
        train(dataclasses.replace(base, init_model=str(tmp_path / "sac.zip")), tmp_path / "other_algo")
    with pytest.raises(ConfigError, match="init_model"):
        TrainConfig(init_model=str(first.model_path), warm_start=WarmStartConfig(steps=10))


def split_weights(model_path: Path) -> tuple[dict, dict]:
    """A saved PPO model's parameters: (value function, everything else)."""
    from stable_baselines3 import PPO

    from negobs_gym.policies.callbacks import CriticWarmupCallback

    named = dict(PPO.load(model_path, device="cpu").policy.named_parameters())
    value = {n: p for n, p in named.items() if n.startswith(CriticWarmupCallback.VALUE_PARAMETERS)}
    return value, {n: p for n, p in named.items() if n not in value}


def _check_critic_warmup_moves_only_the_value_function_then_everything(tmp_path: Path, first) -> None:
    import torch
    from stable_baselines3 import PPO

    tuned = dataclasses.replace(
        SHORT_PPO, init_model=str(first.model_path), critic_warmup_steps=64, target_kl=0.05, steps=64
    )
    warm = train(tuned, tmp_path / "warmup")  # one update, inside the warm-up
    (value0, actor0), (value1, actor1) = split_weights(first.model_path), split_weights(warm.model_path)
    assert actor0.keys() >= {"log_std", "action_net.weight", "mlp_extractor.policy_net.0.weight"}
    assert any(n.startswith("features_extractor.") for n in actor0)
    assert all(torch.equal(actor0[n], actor1[n]) for n in actor0)
    assert all(not n.startswith(("features_extractor", "action_net", "log_std")) for n in value0)
    assert not all(torch.equal(value0[n], value1[n]) for n in value0)
    assert PPO.load(warm.model_path, device="cpu").target_kl == 0.05

    after = train(dataclasses.replace(tuned, steps=128), tmp_path / "after")  # the second update moves all
    actor2 = split_weights(after.model_path)[1]
    assert not torch.equal(actor0["action_net.weight"], actor2["action_net.weight"])

    narrow = train(dataclasses.replace(tuned, init_action_std=0.1), tmp_path / "narrow")
    (_, actor3) = split_weights(narrow.model_path)  # frozen by the warm-up: the std as set
    assert torch.allclose(actor3["log_std"].exp(), torch.full_like(actor3["log_std"], 0.1))
    assert torch.equal(actor3["action_net.weight"], actor0["action_net.weight"])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"algo": "DQN"}, "algo"),
        ({"algo": "SAC", "critic_warmup_steps": 100}, "critic_warmup_steps"),
        ({"critic_warmup_steps": -1}, "critic_warmup_steps"),
        ({"target_kl": float("nan")}, "target_kl"),
        ({"algo": "SAC", "target_kl": 0.01}, "target_kl"),
        ({"init_action_std": 0.1}, "init_action_std"),  # without init_model
        ({"init_model": "m.zip", "init_action_std": -0.1}, "init_action_std"),
        ({"overrides": ("observation.source",)}, "overrides"),  # no =VALUE
        ({"overrides": "observation.source=oracle"}, "overrides"),  # one text, not a tuple of them
        ({"grid_input": 1}, "grid_input"),
        ({"env": ""}, "env"),
        ({"steps": 0}, "steps"),
        ({"envs": 0}, "envs"),
        ({"vec_env": "async"}, "vec_env"),
        ({"learning_rate": 0.0}, "learning_rate"),
        ({"eval_every": -1}, "eval_every"),
    ],
)
def test_bad_config_names_its_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        TrainConfig(**kwargs)


def test_the_filter_is_read_from_the_run_table_of_the_spec(tmp_path: Path) -> None:
    env = make_training_env("paper_n_three_pits", (*ORACLE, "run.filter=true"))
    assert env.unwrapped.scenario.observation.source == "oracle" and env.grid_shape == (4, 36, 16)
    assert isinstance(env.env, BrakingSafetyFilter)  # the policy observation wraps the filter
    assert env.env.config == SCENE_FILTER  # the scene default: Eq. 18 plus hazard memory
    env.close()
    config = TrainConfig(env="paper_n_three_pits", overrides=(*ORACLE, "run.filter=1"))
    with pytest.raises(ConfigError, match=r"run\.filter"):  # a bad value named by its path
        filter_setting(config)
    config = TrainConfig(
        env="paper_n_three_pits", overrides=(*ORACLE, "run.filter=true", "filter.stop_for_positive=true")
    )
    assert filter_setting(config) == dataclasses.replace(SCENE_FILTER, stop_for_positive=True)
    env = make_training_env(config.env, config.overrides)
    assert env.env.config.stop_for_positive
    env.close()
    # the scene's [run] table says filter = true (its scenario test); a run trains without it unless told
    assert load_scenario("paper_n_three_pits").run.filter
    plain = TrainConfig(env="paper_n_three_pits", overrides=ORACLE)
    assert not training_spec(plain).run.filter and filter_setting(plain) is False
    env = make_training_env(plain.env, plain.overrides)
    assert not isinstance(env.env, BrakingSafetyFilter)
    env.close()
    # the rock scene's run table stops for positive obstacles: only with the filter asked for
    rock = TrainConfig(env="rock_on_track_25kmh", overrides=("run.filter=true",))
    assert filter_setting(rock) == SCENE_FILTER
    with pytest.raises(ConfigError, match=r"filter\.stop_for_positive: needs the filter"):
        run_filter(training_spec(TrainConfig(overrides=("filter.stop_for_positive=true",))))


def test_env_names_resolve_or_are_rejected(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="unknown env 'nope'"):
        make_training_env("nope")
    with pytest.raises(ConfigError, match="unknown env"):
        make_training_env(str(tmp_path / "missing.toml"), ORACLE)
    with pytest.raises(ConfigError, match="not a negobs_gym env"):
        make_training_env("CartPole-v1")
    with pytest.raises(ConfigError, match=r"observation\.tighten_pair"):
        make_training_env("negobs_gym/OffroadTrack-v0", ["observation.tighten_pair=true"])


def test_the_env_factory_takes_overrides_for_ids_and_scenarios() -> None:
    from negobs_gym.envs.scenarios import OffroadNavV2Env

    env = make_env(
        "negobs_gym/OffroadTrack-v0", ["observation.source=detector", "observation.tighten_pairs=false"]
    )
    assert type(env.unwrapped) is OffroadNavV2Env and env.unwrapped.scenario.name == "offroad_nav_v2"
    changed = env.unwrapped.scenario.observation
    assert not changed.tighten_pairs and changed.source == "detector"
    plain = make_env("negobs_gym/OffroadTrack-v0", source_overrides("detector"))
    observation = plain.unwrapped.scenario.observation
    assert observation.tighten_pairs
    assert changed == dataclasses.replace(observation, tighten_pairs=False)
    for e in (env, plain):
        e.close()
    env = make_env("paper_n_mud_pit", [*source_overrides(None), "obstacles.0.depth_m=1.2"])
    assert env.unwrapped.scenario.obstacles[0].depth_m == 1.2
    env.close()


def test_a_training_run_keeps_the_specs_ranges_and_its_overrides(tmp_path: Path) -> None:
    """Ranged start speeds and time limits survive every env a run builds: its training envs (in
    the vector env's workers too), its evaluation envs, and the scenario it records."""
    from negobs_gym.policies.training import _env_factory

    scene = tmp_path / "ranged.toml"
    braking = resources.files("negobs_gym.spec").joinpath("scenes/braking_v1.toml").read_text()
    scene.write_text(braking.replace("speed_mps = 6.944444444444445", "speed_mps = [4.0, 7.0]", 1))
    config = dataclasses.replace(SHORT_PPO, env=str(scene), overrides=(*ORACLE, "episode.time_limit_s=3.5"))
    spec = training_spec(config)
    assert spec.start.speed_mps == Range(low=4.0, high=7.0) and spec.episode.time_limit_s == 3.5
    for env in (_env_factory(config)(), make_env(config.env, training_overrides(config))):
        scenario = env.unwrapped.scenario
        assert scenario.start.speed_mps == Range(low=4.0, high=7.0), "the start speed's range was lost"
        assert scenario.episode.time_limit_s == 3.5 and scenario.observation.source == "oracle"
        speeds = [env.reset(seed=seed)[1]["speed_mps"] for seed in range(3)]
        assert all(4.0 <= v <= 7.0 for v in speeds) and len(set(speeds)) == 3  # drawn in the range
        env.close()
    result = train(dataclasses.replace(config, steps=64), tmp_path / "run")
    recorded = spec_from_toml((tmp_path / "run" / "scenario.toml").read_text())
    assert recorded.start.speed_mps == Range(low=4.0, high=7.0) and recorded.episode.time_limit_s == 3.5
    assert not recorded.run.filter
    record = json.loads((tmp_path / "run" / "train.json").read_text())["config"]
    assert record["env"] == str(scene) and record["overrides"] == list(config.overrides)
    from negobs_gym.drivers.zoo import recorded_env

    assert recorded_env(str(result.model_path)) == (str(scene.resolve()), config.overrides)


def test_old_records_translate_to_overrides() -> None:
    from negobs_gym.policies.config import config_from_record

    old = {"env": "negobs_gym/Braking-v1", "algo": "PPO", "source": "detector", "filter": True}
    old |= {"stop_for_positive": True, "warm_start": {"steps": 40, "mirror": True}, "steps": 64}
    old |= {"extractor": {"conv_channels": [8, 8, 8]}, "head": {"modes": 2, "bin_edges": [0.0]}}
    config = config_from_record(old)
    assert config.overrides == (
        "observation.source=detector",
        "run.filter=true",
        "filter.stop_for_positive=true",
    )
    assert config.grid_input and config.warm_start == WarmStartConfig(steps=40, mirror=True)
    assert config.extractor.conv_channels == (8, 8, 8) and config.head.bin_edges == (0.0,)
    # a state-only run of a --set scenario: the oracle grid in the env, none in the policy
    state = config_from_record({"env": "out/scenario.toml", "source": "state", "filter": False})
    assert state.overrides == ("observation.source=oracle", "run.filter=false") and not state.grid_input
    braking = dataclasses.replace(config, env="negobs_gym/Braking-v1")
    assert filter_setting(braking) == dataclasses.replace(SCENE_FILTER, stop_for_positive=True)
    # this version's record reads back as it was written
    assert config_from_record(dataclasses.asdict(config)) == config
    with pytest.raises(ConfigError, match=r"config\.sources: no such setting"):
        config_from_record({"sources": "oracle"})
    with pytest.raises(ConfigError, match=r"config\.warm_start\.step: no such setting"):
        config_from_record({"warm_start": {"step": 3}})
    with pytest.raises(ConfigError, match="filter"):
        config_from_record({"filter": "yes"})


def test_the_copied_fields_still_construct_for_one_release_with_a_warning() -> None:
    with pytest.warns(DeprecationWarning, match="overrides=.*observation.source=oracle"):
        old = TrainConfig(source="state", filter=True, stop_for_positive=True)
    assert old == TrainConfig(
        overrides=("observation.source=oracle", "run.filter=true", "filter.stop_for_positive=true"),
        grid_input=False,
    )
    with pytest.raises(ConfigError, match="source"):
        TrainConfig(source="lidar")


@pytest.mark.slow
@pytest.mark.parametrize("vec_env", ["subproc", "prefetch"])
def test_two_envs_run_in_subprocesses(tmp_path: Path, vec_env: str) -> None:
    result = train(dataclasses.replace(SHORT_PPO, envs=2, n_steps=32, vec_env=vec_env), tmp_path)
    assert result.steps == 128 and result.model_path.is_file()


@pytest.mark.slow
def test_build_ahead_trains_the_weights_subproc_trains(tmp_path: Path) -> None:
    """The workers' worlds built ahead change where the time goes, not one bit of the run."""
    import stable_baselines3

    weights = []
    for vec_env in ("subproc", "build_ahead"):
        # 128 steps per env: Braking-v1's episodes end within ~50, so most resets come after an update
        config = dataclasses.replace(SHORT_PPO, steps=256, envs=2, n_steps=32, vec_env=vec_env)
        result = train(config, tmp_path / vec_env)
        model = stable_baselines3.PPO.load(result.model_path, device="cpu")
        weights.append([p.detach().numpy() for p in model.policy.parameters()])
    assert all(np.array_equal(a, b) for a, b in zip(*weights, strict=True))


def test_tensorboard_only_when_installed(monkeypatch) -> None:
    import importlib.util

    from negobs_gym.policies import training

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda n, *a: None if n == "tensorboard" else real(n, *a)
    )
    assert training.logger_formats() == ["csv"]
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda n, *a: object() if n == "tensorboard" else real(n, *a)
    )
    assert training.logger_formats() == ["csv", "tensorboard"]


def test_a_new_model_has_the_same_weights_whatever_threads_torch_had() -> None:
    """Torch's orthogonal initialisation gives other weights on another thread count; a new
    model draws them on ``torch_threads`` whatever the caller set."""
    import torch

    from negobs_gym.policies.threads import torch_threads
    from negobs_gym.policies.training import _new_model, _vec_env

    config = TrainConfig(env="negobs_gym/OffroadNav-v1", overrides=ORACLE, n_steps=64)
    venv = _vec_env(config)
    weights = []
    try:
        for caller_threads in (1, 2):
            with torch_threads(caller_threads):
                model = _new_model(config, venv, (2, 36, 16))
                assert torch.get_num_threads() == caller_threads  # restored
            weights.append([p.detach().clone() for p in model.policy.parameters()])
    finally:
        venv.close()
    assert all(torch.equal(a, b) for a, b in zip(*weights, strict=True))
