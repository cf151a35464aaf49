"""Keyed range noise: its draws against a numpy spelling on the SplitMix64 definition."""

from __future__ import annotations

import numpy as np
import pytest

from negobs_gym.errors import InterfaceError
from negobs_gym.sensors.noise import NoiseConfig, add_keyed_noise, apply_keyed_noise


def _splitmix64(x: np.ndarray) -> np.ndarray:
    """Steele et al. 2014's finaliser on uint64 arrays (arithmetic mod 2^64)."""
    with np.errstate(over="ignore"):
        z = x + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def test_keyed_noise_moves_hits_by_about_sigma_and_keeps_misses():
    ranges = np.full(20000, 10.0)
    ranges[::10] = np.nan
    noisy = apply_keyed_noise(ranges, np.arange(ranges.size), NoiseConfig(dropout_prob=0.0), key=7)
    assert np.isnan(noisy[::10]).all()
    hit = ~np.isnan(ranges)
    assert abs(np.std(noisy[hit] - 10.0) - 0.02) < 0.002
    np.testing.assert_array_equal(
        apply_keyed_noise(ranges[1:3], np.arange(1, 3), NoiseConfig(dropout_prob=0.0), key=7), noisy[1:3]
    )


def _numpy_keyed_noise(ranges: np.ndarray, index: np.ndarray, config: NoiseConfig, key: int) -> np.ndarray:
    """The keyed noise spelled out in numpy (the compiled version must equal it bit for bit)."""
    r = np.array(ranges, dtype=np.float64)
    hit = np.flatnonzero(~np.isnan(r))
    bits = _splitmix64(index[hit].astype(np.uint64) ^ _splitmix64(np.array([key], dtype=np.uint64)))
    scale = np.float32(1.0 / 2**24)
    u1 = ((bits >> np.uint64(40)).astype(np.float32) + np.float32(0.5)) * scale
    u2 = (((bits >> np.uint64(16)) & np.uint64(0xFFFFFF)).astype(np.float32) + np.float32(0.5)) * scale
    u3 = (bits & np.uint64(0xFFFF)).astype(np.float32) * np.float32(1.0 / 2**16)
    normal = np.sqrt(np.float32(-2.0) * np.log(u1)) * np.cos(np.float32(2.0 * np.pi) * u2)
    noisy = r[hit] + config.range_sigma_m * normal
    noisy[(u3 < np.float32(config.dropout_prob)) | (noisy < 0)] = np.nan
    r[hit] = noisy
    return r


def test_keyed_noise_equals_its_numpy_spelling_bit_for_bit():
    rng = np.random.default_rng(3)
    ranges = rng.uniform(0.0, 80.0, 50000)
    ranges[rng.random(ranges.size) < 0.3] = np.nan
    ranges[:50] = rng.uniform(0.0, 0.01, 50)  # noise can push these below 0: dropped
    index = np.sort(rng.choice(2**40, ranges.size, replace=False))
    index[:3] = [0, 1, 2]
    for config in (NoiseConfig(), NoiseConfig(range_sigma_m=0.5, dropout_prob=0.2)):
        for key in (0, 1, 99, 2**63 - 1, 2**64 - 1, 12345678901234567):
            got = apply_keyed_noise(ranges, index, config, key)
            want = _numpy_keyed_noise(ranges, index, config, key)
            np.testing.assert_array_equal(got, want)
            assert np.isnan(got).sum() > np.isnan(ranges).sum()  # dropouts and negatives happened


@pytest.mark.parametrize("config", [NoiseConfig(), NoiseConfig(enabled=False)])
def test_keyed_noise_in_place_masks_the_near_limit_first(config):
    rng = np.random.default_rng(4)
    ranges = rng.uniform(0.0, 30.0, 20000)
    ranges[rng.random(ranges.size) < 0.2] = np.nan
    index = np.arange(ranges.size, dtype=np.int32) * 3  # int32 indices draw what int64 ones draw
    near = ranges.copy()
    near[near < 0.9] = np.nan
    buffer = ranges.copy()
    add_keyed_noise(buffer, index, config, 42, min_range_m=0.9)
    np.testing.assert_array_equal(buffer, apply_keyed_noise(near, index.astype(np.int64), config, 42))
    assert np.isnan(buffer[ranges < 0.9]).all()


def test_keyed_noise_of_a_fortran_ordered_image_is_its_c_ordered_copys():
    rng = np.random.default_rng(5)
    image = rng.uniform(1.0, 50.0, (16, 300))
    index = np.arange(image.size)
    got = apply_keyed_noise(np.asfortranarray(image), index, NoiseConfig(), 9)
    np.testing.assert_array_equal(got, apply_keyed_noise(image, index, NoiseConfig(), 9))
    assert not np.array_equal(got, image)


def test_keyed_noise_refuses_an_index_that_does_not_match_the_ranges():
    with pytest.raises(InterfaceError, match="ray_index"):
        apply_keyed_noise(np.ones(5), np.arange(4), NoiseConfig(), 1)
    with pytest.raises(InterfaceError, match="ray_index"):
        apply_keyed_noise(np.ones(3), np.array([0.0, 1.0, 2.0]), NoiseConfig(), 1)
