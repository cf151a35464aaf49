import numpy as np
import pytest

from negobs_gym.errors import ConfigError, InterfaceError, UnknownNameError
from negobs_gym.sensors import (
    LidarModel,
    SensorMount,
    hdl32e,
    hdl64e_s2,
    hdl64e_s2_nominal,
    ibeo_lux,
    paper_n_rig,
    paper_n_rig_reduced,
    paper_t_rig,
)
from negobs_gym.sensors.calibration import HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD


def test_hdl64_calibrated_table():
    m = hdl64e_s2()
    assert m.n_lasers * m.n_columns == 256000
    el = np.asarray(m.elevation_deg)
    assert np.all(np.diff(el) > 0)  # detector order: ascending elevation (paper N §3.1)
    # the unit's table, not the uniform nominal one: same span within ~3 deg, uneven spacing
    np.testing.assert_allclose(np.sort(np.rad2deg(HDL64E_S2_SZTAKI_VERT_CORRECTION_RAD)), el)
    assert el[0] == pytest.approx(-24.845, abs=1e-3) and el[-1] == pytest.approx(4.970, abs=1e-3)
    assert np.ptp(np.diff(el)) > 0.3
    assert paper_n_rig().mount("hdl64").model == m
    reduced = paper_n_rig_reduced().mount("hdl64").model
    assert reduced.elevation_deg == m.elevation_deg[::2] and reduced.n_columns == 1000
    assert paper_n_rig_reduced(hdl64e_s2_nominal()).mount("hdl64").model.n_lasers == 32


def test_tables():
    assert hdl64e_s2_nominal().n_lasers * hdl64e_s2_nominal().n_columns == 256000
    el = hdl32e().elevation_deg
    assert el[0] == pytest.approx(-30.67) and el[-1] == pytest.approx(10.67, abs=1e-6)
    assert ibeo_lux().elevation_deg == (-1.2, -0.4, 0.4, 1.2)
    assert np.all(np.diff(ibeo_lux().azimuth_rad) > 0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"elevation_deg": ()}, "elevation_deg"),
        ({"azimuth_resolution_deg": 0.0}, "azimuth_resolution_deg"),
        ({"azimuth_resolution_deg": -1.0}, "azimuth_resolution_deg"),
        ({"hfov_deg": 400.0}, "hfov_deg"),
        ({"hfov_deg": 0.0}, "hfov_deg"),
        ({"max_range_m": float("nan")}, "max_range_m"),
    ],
)
def test_bad_model(kwargs, field):
    base = {"name": "x", "elevation_deg": (0.0, 1.0), "azimuth_resolution_deg": 1.0}
    with pytest.raises(ConfigError, match=field):
        LidarModel(**{**base, **kwargs})


def test_paper_t_rig_puts_the_lux_on_the_front_bumper():
    from negobs_gym.sim.vehicle import VehicleConfig

    vehicle = VehicleConfig()
    (lux,) = paper_t_rig().mounts
    x, forward, height = lux.translation_m
    assert (x, height) == (0.0, 0.65)
    assert 0.0 < forward - (vehicle.length_m - vehicle.rear_overhang_m) <= 0.1  # just beyond the body
    assert paper_t_rig(forward_m=2.0).mounts[0].translation_m == (0.0, 2.0, 0.65)
    with pytest.raises(ConfigError, match="forward_m"):
        paper_t_rig(forward_m=float("nan"))


def test_bad_rotation():
    with pytest.raises(ConfigError, match="rotation"):
        SensorMount(name="s", model=hdl32e(), rotation=(1.0, 0.1, 0, 0, 1, 0, 0, 0, 1))


def test_unknown_mount_and_missing_rng_raise_package_errors():
    from negobs_gym.sensors.noise import NoiseConfig, apply_noise
    from negobs_gym.sensors.rigs import paper_n_rig

    rig = paper_n_rig()
    with pytest.raises(UnknownNameError, match="no sensor 'lux'") as err:
        rig.mount("lux")
    assert isinstance(err.value, KeyError)  # callers catching KeyError keep working
    with pytest.raises(InterfaceError, match="rng") as err:
        apply_noise(np.ones(3), NoiseConfig(enabled=True), rng=None)
    assert isinstance(err.value, TypeError)
