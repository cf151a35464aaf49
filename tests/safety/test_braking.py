import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.safety import braking_distance_m, max_safe_speed_mps


def test_eq18_at_25_kmh():
    assert float(braking_distance_m(25 / 3.6)) == pytest.approx(10.52, abs=0.005)


def test_zero_speed_is_buffer():
    assert float(braking_distance_m(0.0)) == 5.0


def test_inverse_round_trip():
    v = np.linspace(0, 20, 41)
    assert np.allclose(max_safe_speed_mps(braking_distance_m(v)), v)


def test_inverse_edges():
    assert float(max_safe_speed_mps(3.0)) == 0.0
    assert np.isposinf(max_safe_speed_mps(np.inf))


@pytest.mark.parametrize(
    "kw", [{"mu": 0.0}, {"mu": -1}, {"g": 0}, {"reaction_time_s": -0.1}, {"buffer_m": np.nan}]
)
def test_bad_config(kw):
    with pytest.raises(ConfigError):
        braking_distance_m(1.0, **kw)
