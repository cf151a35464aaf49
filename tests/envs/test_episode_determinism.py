"""Same seed, same episode bit for bit: fresh or kept worlds, ROI casting, across processes and CPUs."""

from __future__ import annotations

import math
import os
import platform
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs

ENV_ID = "negobs_gym/OffroadNav-v0"
SHORT = {"terrain.params.length_m": 60.0}  # the shortest winding course: a world builds ~4x faster
STEPS = 12
ROOT = Path(__file__).resolve().parents[2]


def _actions() -> np.ndarray:
    rng = np.random.default_rng(123)
    return rng.uniform(-0.3, 1.0, size=(STEPS, 2)).astype(np.float32)


def _rollout(env: gym.Env, seed: int) -> dict[str, np.ndarray]:
    """Observations, poses and the raw scans of every frame (the rays cast, ranges and noise)."""
    scans = []
    base = env.unwrapped
    observe = base._observe

    def observe_and_keep_scans():
        out = observe()
        perception = base._grid_source.perception
        cast = perception.far_scans or perception.scans  # a far-part step's own, else the frame's
        # each frame's length first: cropped range images may differ in width from frame to frame
        scans.append(np.concatenate([[s.ranges_m.size, *s.ranges_m.ravel()] for s in cast.values()]))
        return out

    base._observe = observe_and_keep_scans
    try:
        obs, info = env.reset(seed=seed)
        grids, states, poses = [obs["grid"]], [obs["state"]], [info["pose"]]
        for a in _actions():
            obs, _, term, trunc, info = env.step(a)
            grids.append(obs["grid"])
            states.append(obs["state"])
            poses.append(info["pose"])
            if term or trunc:
                break
    finally:
        del base._observe  # back to the class's method
    return {
        "grid": np.stack(grids),
        "state": np.stack(states),
        "pose": np.stack(poses),
        "scans": np.concatenate(scans),
    }


def _assert_same(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> None:
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].shape == b[k].shape, k
        assert np.array_equal(a[k], b[k], equal_nan=True), f"{k} differs"


def test_default_observation_uses_the_roi_rig():
    env = gym.make(ENV_ID)
    assert env.unwrapped.scenario.observation.rig == "roi"
    env.close()


def _short_env(**overrides) -> gym.Env:
    """The default env on the shortest winding course (what is tested does not depend on its length)."""
    return gym.make(ENV_ID, overrides={**SHORT, **overrides})


def test_kept_world_replays_the_episode_bit_for_bit():
    env = _short_env(**{"episode.world_cache_size": 2})
    first = _rollout(env, seed=5)
    assert first["grid"][1:].any(), "the detector grid must see something for the test to mean anything"
    _rollout(env, seed=6)
    cache = env.unwrapped._worlds
    hits = cache.hits
    again = _rollout(env, seed=5)  # kept world, restored from its settled state
    assert cache.hits == hits + 1
    env.close()
    _assert_same(first, again)


def _in_another_process(names: str, *lines: str, env: dict | None = None) -> None:
    """Run ``lines`` in a fresh Python process that imported ``names`` from this module."""
    code = "\n".join(
        [
            "import sys, numpy as np, gymnasium as gym",
            f"sys.path.insert(0, {str(ROOT)!r})",
            f"from tests.envs.test_episode_determinism import {names}",
            *lines,
        ]
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT, timeout=300, env=env)


def _far_part_env() -> gym.Env:
    """A frame every 3rd step, the grid beyond 8 m cast and detected between."""
    return _short_env(**{"observation.scan_every": 3, "observation.scan_far_from_m": 8.0})


def _frames(seed: int) -> np.ndarray:
    """The ``rgb_array`` frames of a Braking-v1 episode's reset and first steps at full throttle."""
    env = gym.make("negobs_gym/Braking-v1", render_mode="rgb_array")
    env.reset(seed=seed)
    frames = [env.render()]
    for _ in range(4):
        env.step(np.array([1.0, 0.0], np.float32))
        frames.append(env.render())
    env.close()
    return np.stack(frames)


def test_same_seed_same_episode_far_part_steps_and_frames_in_another_process(tmp_path):
    """One fresh process (one start-up, not three) runs the default env's episode, the far-part
    steps' episode (seed 11 each) and Braking-v1's rendered frames (seed 3); this process runs
    them too. Rendering draws from no generator: the frames (what `negobs eval video` encodes)
    are the episode's, pixel for pixel, in any process."""
    _in_another_process(
        "_rollout, _short_env, _far_part_env, _frames",
        f"np.savez({str(tmp_path / 'episode.npz')!r}, **_rollout(_short_env(), seed=11))",
        f"np.savez({str(tmp_path / 'far_part.npz')!r}, **_rollout(_far_part_env(), seed=11))",
        f"np.save({str(tmp_path / 'frames.npy')!r}, _frames(seed=3))",
    )
    env = _short_env()
    here = _rollout(env, seed=11)
    env.close()
    with np.load(tmp_path / "episode.npz") as there:
        _assert_same(here, dict(there))
    env = _far_part_env()
    here = _rollout(env, seed=11)
    env.close()
    assert here["grid"][1:].any()
    with np.load(tmp_path / "far_part.npz") as there:
        _assert_same(here, dict(there))
    frames = _frames(seed=3)
    assert frames.std() > 0 and not np.array_equal(frames[0], frames[-1])  # a picture that moves
    assert np.array_equal(frames, np.load(tmp_path / "frames.npy"))


def _pinned_rollout(seed: int) -> dict[str, np.ndarray]:
    """An episode with Embree's kernels pinned to AVX2, after another episode in the same env."""
    env = _short_env(**{"observation.raycast_isa": "avx2"})
    _rollout(env, seed=seed + 1)
    episode = _rollout(env, seed=seed)
    env.close()
    return episode


# numpy's AVX-512 dispatch targets (numpy >= 2.3); without them numpy runs what an AVX2 CPU runs
_NO_AVX512 = {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR", "OPENBLAS_CORETYPE": "Haswell"}


def _numpy_takes_avx512_paths() -> bool:
    y, x = np.random.default_rng(0).uniform(-10.0, 10.0, (2, 1000))  # contiguous: SIMD paths take these
    return not np.array_equal(np.arctan2(y, x), [math.atan2(a, b) for a, b in zip(y, x, strict=True)])


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="x86 instruction sets")
@pytest.mark.skipif(not _numpy_takes_avx512_paths(), reason="numpy runs no AVX-512 routines on this CPU")
def test_same_seed_same_scans_on_an_avx2_cpu(tmp_path):
    """With ``raycast_isa="avx2"`` an AVX-512 machine casts, detects and observes as an AVX2 one.

    The other process runs numpy (and OpenBLAS) as on an AVX2 CPU: the routines numpy picks by CPU
    differ there (checked), so any of them left on the episode's path would show.
    """
    out = tmp_path / "episode.npz"
    _in_another_process(
        "_numpy_takes_avx512_paths, _pinned_rollout",
        "assert not _numpy_takes_avx512_paths(), 'numpy still takes its AVX-512 routines'",
        f"np.savez({str(out)!r}, **_pinned_rollout(seed=13))",
        env={**os.environ, **_NO_AVX512},
    )
    here = _pinned_rollout(seed=13)
    assert np.isfinite(here["scans"]).mean() > 0.2
    with np.load(out) as there:
        _assert_same(here, dict(there))


def test_terrain_pool_gives_each_index_its_own_terrain():
    changes = {"episode.terrain_pool_size": 3, "episode.world_cache_size": 3, "observation.source": "oracle"}
    env = _short_env(**changes)
    seen: dict[str, np.ndarray] = {}
    for seed in range(8):
        env.reset(seed=seed)
        key = next(reversed(env.unwrapped._worlds._worlds))
        heights = env.unwrapped.terrain.heightfield.heights_m
        if key in seen:
            assert np.array_equal(seen[key], heights)
        seen[key] = np.array(heights)
    assert 1 < len(seen) <= 3 and len(env.unwrapped._worlds) <= 3
    env.close()
