"""train(): SAC on the state alone from a scenario TOML, resume, and what a resumed run must match."""

from __future__ import annotations

import dataclasses
import json
import shutil
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.policies.callbacks import latest_checkpoint
from negobs_gym.policies.config import TrainConfig, WarmStartConfig
from negobs_gym.policies.training import filter_setting, make_env, make_task_env, train
from negobs_gym.safety import SafetyFilterConfig


def test_sac_state_only_from_a_toml_spec_resumes(tmp_path: Path) -> None:
    spec = tmp_path / "my_braking.toml"
    shutil.copy(resources.files("negobs_gym.scenarios").joinpath("scenes/braking_v1.toml"), spec)
    config = TrainConfig(
        env=str(spec),
        algo="SAC",
        source="state",
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

    with pytest.raises(ConfigError, match="resume"):
        train(dataclasses.replace(config, steps=240, source="oracle"), out, resume=True)
    with pytest.raises(ConfigError, match="nothing to train"):
        train(dataclasses.replace(config, steps=150), out, resume=True)


#: A short PPO run on the oracle grid: 64-step rollouts, one evaluation episode at the end.
SHORT_PPO = TrainConfig(
    env="negobs_gym/Braking-v1",
    source="oracle",
    steps=128,
    n_steps=64,
    eval_every=0,
    eval_episodes=1,
    checkpoint_every=0,
    progress=False,
)


@pytest.fixture(scope="module")
def short_ppo_64(tmp_path_factory: pytest.TempPathFactory):
    """One 64-step :data:`SHORT_PPO` run (one rollout, one update): the model two tests start from,
    which they only read."""
    return train(dataclasses.replace(SHORT_PPO, steps=64), tmp_path_factory.mktemp("short_ppo_64"))


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


def test_init_fine_tunes_a_trained_model_on_another_source(tmp_path: Path, short_ppo_64) -> None:
    import torch
    from stable_baselines3 import PPO

    base, first = dataclasses.replace(SHORT_PPO, steps=64), short_ppo_64
    tuned = dataclasses.replace(
        base, source="state", init_model=str(first.model_path), learning_rate=1e-3, eval_seed=7
    )
    with pytest.raises(ConfigError, match="init_model"):  # the state-only policy has no grid input
        train(tuned, tmp_path / "bad")

    tuned = dataclasses.replace(tuned, source="detector", steps=64, n_steps=32)
    second = train(tuned, tmp_path / "detector")
    rows = second.eval_csv.read_text().splitlines()[1:]
    assert [r.split(",")[0] for r in rows] == ["0", "64"]  # the init model's row first; steps from 0
    model = PPO.load(second.model_path, device="cpu")
    assert model.num_timesteps == 64 and model.n_steps == 32 and model.learning_rate == 1e-3
    assert not torch.equal(policy_weights(first.model_path), policy_weights(second.model_path))  # trained
    record = json.loads((tmp_path / "detector" / "train.json").read_text())
    assert record["config"]["init_model"] == str(first.model_path)
    assert record["config"]["eval_seed"] == 7
    with pytest.raises(ConfigError, match="init_model"):
        train(dataclasses.replace(base, init_model="no_such_policy"), tmp_path / "missing")
    from stable_baselines3 import SAC

    env = make_env(base.env, "oracle", use_filter=False)
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


def test_critic_warmup_moves_only_the_value_function_then_everything(tmp_path: Path, short_ppo_64) -> None:
    import torch
    from stable_baselines3 import PPO

    first = short_ppo_64
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
        ({"source": "lidar"}, "source"),
        ({"steps": 0}, "steps"),
        ({"envs": 0}, "envs"),
        ({"vec_env": "async"}, "vec_env"),
        ({"learning_rate": 0.0}, "learning_rate"),
        ({"eval_every": -1}, "eval_every"),
        ({"stop_for_positive": True}, "stop_for_positive"),  # without filter
        ({"filter": True, "stop_for_positive": 1}, "stop_for_positive"),
    ],
)
def test_bad_config_names_its_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        TrainConfig(**kwargs)


def test_env_names_resolve_or_are_rejected(tmp_path: Path) -> None:
    env = make_env("paper_n_three_pits", "oracle", use_filter=True)
    assert env.unwrapped.config.observation.source == "oracle" and env.grid_shape == (4, 36, 16)
    assert env.env.config == SafetyFilterConfig()  # the policy observation wraps the filter
    env.close()
    config = TrainConfig(env="paper_n_three_pits", filter=True, stop_for_positive=True)
    env = make_env(config.env, "oracle", use_filter=filter_setting(config))
    assert env.env.config.stop_for_positive
    env.close()
    with pytest.raises(ConfigError, match="unknown env 'nope'"):
        make_task_env("nope", "oracle")
    with pytest.raises(ConfigError, match="unknown env"):
        make_task_env(str(tmp_path / "missing.toml"), "oracle")
    with pytest.raises(ConfigError, match="not a negobs_gym env"):
        make_task_env("CartPole-v1", "oracle")


def test_task_env_takes_overrides_for_ids_and_scenarios() -> None:
    from negobs_gym.envs.scenarios import OffroadNavV2Env

    env = make_task_env("negobs_gym/OffroadTrack-v0", "detector", ["observation.tighten_pairs=false"])
    assert type(env) is OffroadNavV2Env and env.scenario.name == "offroad_nav_v2"
    assert not env.config.observation.tighten_pairs and env.config.observation.source == "detector"
    plain = make_task_env("negobs_gym/OffroadTrack-v0", "detector")
    assert plain.unwrapped.config.observation.tighten_pairs
    observation = plain.unwrapped.config.observation
    assert env.config.observation == dataclasses.replace(observation, tighten_pairs=False)
    for e in (env, plain):
        e.close()
    env = make_task_env("paper_n_mud_pit", None, ["obstacles.0.depth_m=1.2"])
    assert env.scenario.obstacles[0].depth_m == 1.2
    env.close()
    with pytest.raises(ConfigError, match=r"observation\.tighten_pair"):
        make_task_env("negobs_gym/OffroadTrack-v0", None, ["observation.tighten_pair=true"])


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

    config = TrainConfig(env="negobs_gym/OffroadNav-v1", source="oracle", n_steps=64)
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
