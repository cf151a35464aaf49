"""Vectorized envs (gymnasium async, SB3 SubprocVecEnv) and cross-process determinism."""

from __future__ import annotations

import json
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.errors import ConfigError, ResetNeeded, WorkerError

_ROLLOUT = """
import json, gymnasium as gym, numpy as np, negobs_gym
def rollout():
    env = gym.make("negobs_gym/Braking-v0")
    obs, _ = env.reset(seed=5)
    out = [obs["state"].tolist(), int(obs["grid"].sum())]
    for k in range(3):
        obs, r, *_ = env.step(np.array([0.4, 0.3 * (-1) ** k], np.float32))
        out += [obs["state"].tolist(), int(obs["grid"].sum()), float(r)]
    env.close()
    return json.dumps(out)
"""


def test_one_seed_gives_identical_rollouts_in_two_processes() -> None:
    """The same code in a fresh process and in this one (another hash seed, other envs before)."""
    done = subprocess.run(
        [sys.executable, "-c", _ROLLOUT + "print(rollout())"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    here: dict = {}
    exec(_ROLLOUT, here)
    # exact: floats round-trip through JSON repr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == json.loads(here["rollout"]())


def test_gymnasium_async_vector_env_runs() -> None:
    venv = gym.make_vec("negobs_gym/Braking-v0", num_envs=2, vectorization_mode="async")
    obs, _ = venv.reset(seed=[1, 2])
    assert obs["grid"].shape[0] == 2
    obs, reward, *_ = venv.step(np.zeros((2, 2), np.float32))
    assert reward.shape == (2,) and np.all(np.isfinite(reward))
    venv.close()


def _make_braking() -> gym.Env:
    # "module:id" makes gymnasium import negobs_gym (and so register) inside the subprocess
    return gym.make("negobs_gym:negobs_gym/Braking-v0")


def test_sb3_subproc_vec_env_runs() -> None:
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = SubprocVecEnv([_make_braking for _ in range(2)])
    venv.seed(3)
    obs = venv.reset()
    assert obs["state"].shape == (2, 5)
    obs, reward, _, _ = venv.step(np.zeros((2, 2), np.float32))
    assert reward.shape == (2,)
    venv.close()


def _make_short_braking() -> gym.Env:
    """Braking-v0 (default observation: detector grid, ROI rig) cut to 3-step episodes."""
    return gym.make("negobs_gym:negobs_gym/Braking-v0", max_episode_steps=3)


def _actions(k: int) -> np.ndarray:
    return np.array([[0.5, 0.2 * (-1) ** k], [0.3, -0.1]], np.float32)


def _same(a, b) -> bool:
    return all(np.array_equal(a[key], b[key]) for key in a)


def test_prefetch_vec_env_episodes_equal_single_envs_reset_with_their_seeds() -> None:
    from negobs_gym.envs.vector import PrefetchVecEnv, episode_seed

    venv = PrefetchVecEnv([_make_short_braking, _make_short_braking])
    venv.seed(11)
    first = venv.reset()
    steps = []
    for k in range(7):  # episodes 0 and 1 end on steps 2 and 5; episode 2 has begun
        steps.append(venv.step(_actions(k)))
    assert venv.episode_seeds() == [episode_seed(11, i, 2) for i in range(2)]
    venv.close()
    for slot in range(2):
        env = _make_short_braking()
        for episode in range(3):
            obs, _ = env.reset(seed=episode_seed(11, slot, episode))
            start = 3 * episode
            if episode == 0:
                assert _same(obs, {key: v[slot] for key, v in first.items()})
            else:  # the step that ended the previous episode returned this episode's first observation
                assert _same(obs, {key: v[slot] for key, v in steps[start - 1][0].items()})
            for k in range(start, min(start + 3, len(steps))):
                obs, reward, terminated, truncated, _ = env.step(_actions(k)[slot])
                vec_obs, vec_reward, vec_done, vec_info = steps[k]
                assert vec_reward[slot] == reward and vec_done[slot] == (terminated or truncated)
                if vec_done[slot]:
                    assert _same(obs, vec_info[slot]["terminal_observation"])
                    assert vec_info[slot]["TimeLimit.truncated"] == (truncated and not terminated)
                else:
                    assert _same(obs, {key: v[slot] for key, v in vec_obs.items()})
        env.close()


def test_prefetch_vec_env_reaches_both_processes_and_reports_worker_errors() -> None:
    import pytest

    from negobs_gym.envs.vector import PrefetchVecEnv

    venv = PrefetchVecEnv([_make_short_braking])
    with pytest.raises(ResetNeeded, match=r"call reset\(\) before step\(\)"):  # a RuntimeError too
        venv.step(_actions(0)[:1])
    venv.seed(0)
    venv.reset()
    venv.wait_for_spares()
    venv.set_attr("probe_value", 7)
    assert venv.get_attr("probe_value") == [7]
    venv.step(_actions(0)[:1])
    venv.step(_actions(1)[:1])
    venv.step(_actions(2)[:1])  # the episode ends: the spare, which also got the attribute, steps on
    assert venv.get_attr("probe_value") == [7]
    with pytest.raises(WorkerError, match="worker failed"):  # also a RuntimeError
        venv.env_method("no_such_method")
    assert venv.env_is_wrapped(gym.wrappers.TimeLimit) == [True]
    with pytest.raises(ConfigError, match=r"^seed: must be") as bad_seed:
        venv.seed(-1)
    assert bad_seed.value.field == "seed" and isinstance(bad_seed.value, ValueError)
    venv.close()
    with pytest.raises(ConfigError, match=r"^env_fns: must hold at least one") as empty:
        PrefetchVecEnv([])
    assert empty.value.field == "env_fns"


class _ResetProbe(gym.Wrapper):
    """Reports in its reset info the ``probe_value`` attribute it had when it reset."""

    probe_value = None

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, {**info, "probe_at_reset": self.probe_value}


def _make_probed_braking() -> gym.Env:
    return _ResetProbe(_make_short_braking())


def test_prefetch_vec_env_next_episode_starts_after_set_attr_and_env_method() -> None:
    from negobs_gym.envs.vector import PrefetchVecEnv, episode_seed

    venv = PrefetchVecEnv([_make_probed_braking])
    venv.seed(4)
    venv.reset()
    venv.wait_for_spares()  # the spare has reset episode 1 before the change below
    venv.set_attr("probe_value", 7)
    for k in range(3):
        venv.step(_actions(k)[:1])
    assert venv.reset_infos[0]["probe_at_reset"] == 7  # episode 1 was reset again after the change
    venv.env_method("__setattr__", "probe_value", 8)
    for k in range(3):
        venv.step(_actions(k)[:1])
    assert venv.reset_infos[0]["probe_at_reset"] == 8
    assert venv.episode_seeds() == [episode_seed(4, 0, 2)]  # the same seeds as without the changes
    venv.close()


def test_prefetch_vec_env_closes_while_spares_still_reset() -> None:
    from negobs_gym.envs.vector import PrefetchVecEnv

    venv = PrefetchVecEnv([_make_short_braking])
    venv.seed(1)
    venv.reset()  # the spare is still building its first episode
    venv.close()
    assert all(not p.process.is_alive() for p in venv._active + venv._spare)


def _make_broken() -> gym.Env:
    raise ValueError("this env cannot be built")


def test_prefetch_vec_env_reports_an_env_that_cannot_be_built() -> None:
    import pytest

    from negobs_gym.envs.vector import PrefetchVecEnv

    with pytest.raises(WorkerError, match="this env cannot be built") as failed:
        PrefetchVecEnv([_make_broken])
    assert isinstance(failed.value, RuntimeError)


class _FrameFlag(gym.Wrapper):
    """Adds ``info["frame"]``: whether this step cast a whole LiDAR frame (its hazards are fresh)."""

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        info = dict(info, frame=self.env.unwrapped.hazard_state().perception_age_s == 0.0)
        return obs, reward, terminated, truncated, info


def _clocked_braking(episode_steps: int) -> gym.Env:
    """Braking-v0 with a frame every 3rd step on the env's clock, cut to ``episode_steps``."""
    from negobs_gym.envs import BrakingEnv

    changes = {"observation.scan_every": 3, "observation.scan_clock": "env", "start.speed_mps": 0.0}
    env = gym.wrappers.TimeLimit(BrakingEnv(overrides=changes), episode_steps)
    return _FrameFlag(env)


def _clocked_braking_4() -> gym.Env:
    return _clocked_braking(4)


def _clocked_braking_5() -> gym.Env:
    return _clocked_braking(5)


def test_prefetch_vec_env_puts_its_slots_frames_on_its_own_steps() -> None:
    """scan_clock = "env": the slots' episodes end at different steps (4 and 5 long) and their
    spares reset without stepping, yet both slots cast on the vector's steps 3, 6, 9, ..."""
    from negobs_gym.envs.vector import PrefetchVecEnv

    venv = PrefetchVecEnv([_clocked_braking_4, _clocked_braking_5])
    venv.seed(2)
    venv.reset()
    frames, dones = [], []
    for k in range(13):
        _, _, done, infos = venv.step(_actions(k))
        frames.append([info["frame"] for info in infos])
        dones.append(done.tolist())
    venv.close()
    assert sum(d[0] for d in dones) == 3 and sum(d[1] for d in dones) == 2  # several swaps each
    assert frames == [[(k + 1) % 3 == 0] * 2 for k in range(13)]


def test_sync_scan_clock_moves_the_next_frames_and_refuses_bad_counts() -> None:
    env = _clocked_braking(50).unwrapped
    env.reset(seed=0)
    env.sync_scan_clock(7)  # the next frame at count 9: two steps on
    fresh = []
    for _ in range(4):
        env.step(np.array([0.0, 0.0], np.float32))
        fresh.append(env.hazard_state().perception_age_s == 0.0)
    assert fresh == [False, True, False, False]
    for bad in (-1, 2.0, True, "3"):
        with pytest.raises(ConfigError, match="env_steps"):
            env.sync_scan_clock(bad)
    env.close()
