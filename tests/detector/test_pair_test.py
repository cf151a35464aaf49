import numpy as np
import pytest

from negobs_gym.detector.config import PairTestConfig
from negobs_gym.detector.pair_test import pair_test
from negobs_gym.errors import ConfigError

SENSOR = np.array([0.0, 0.0, 2.2])
CFG = PairTestConfig()


def run(a, b, c):
    return pair_test(np.array([a]), np.array([b]), np.array([c]), SENSOR, 2.2, CFG)[0]


def test_pass_case_hand_values():
    # d_AB = 1.0, d_BC = 0, dz_BC = 0.1 >= 0.15 * 2.2 * 1.0 / 8 = 0.04125
    assert run([0, 8, 0], [0, 9, -0.3], [0, 9, -0.2])


def test_too_narrow_fails():
    assert not run([0, 8, 0], [0, 8.29, -0.3], [0, 8.29, -0.2])
    assert run([0, 8, 0], [0, 8.31, -0.3], [0, 8.31, -0.2])


def test_gamma1_fails_when_bc_too_wide():
    # d_AB = 1.0 < 1.5 * d_BC = 1.5 * 0.7
    assert not run([0, 8, 0], [0, 9, -0.3], [0, 9.7, -0.2])
    assert run([0, 8, 0], [0, 9, -0.3], [0, 9.6, -0.2])


def test_dz_too_small_fails():
    need = 0.15 * 2.2 * 1.0 / 8.0
    assert not run([0, 8, 0], [0, 9, -0.3], [0, 9, -0.3 + need * 0.9])
    assert run([0, 8, 0], [0, 9, -0.3], [0, 9, -0.3 + need * 1.1])


def test_nan_c_fails():
    assert not run([0, 8, 0], [0, 9, -0.3], [np.nan] * 3)


def test_config_validation_names_field():
    with pytest.raises(ConfigError, match="w_min_m"):
        PairTestConfig(w_min_m=-1)
    with pytest.raises(ConfigError, match="gamma2"):
        PairTestConfig(gamma2=np.nan)


def test_one_origin_per_triple_reads_each_from_its_own():
    a = np.array([[0, 8, 0], [0, 8, 0]])
    b = np.array([[0, 9, -0.3], [0, 9, -0.3]])
    c = np.array([[0, 9, -0.256], [0, 9, -0.256]])
    # dz_BC = 0.044 >= 0.15 * 2.2 * 1.0 / y_A: passes from 8 m (0.041), fails from 7 m (0.047)
    origins = np.array([[0.0, 0.0, 2.2], [0.0, 1.0, 2.2]])
    assert pair_test(a, b, c, origins, 2.2, CFG).tolist() == [True, False]
    assert pair_test(a, b, c, SENSOR, 2.2, CFG).tolist() == [True, True]
