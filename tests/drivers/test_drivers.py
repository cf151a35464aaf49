import numpy as np
import pytest

from negobs_gym.drivers import (
    ConstantSpeedDriver,
    Driver,
    PurePursuitConfig,
    PurePursuitDriver,
    RecklessDriver,
)
from negobs_gym.errors import ActionError, ConfigError

L, MAX_STEER, DT = 2.8, float(np.deg2rad(35)), 0.1


def bicycle(route, driver, steps):
    """Kinematic bicycle stand-in (yaw 0 faces +Y, left positive); returns the driven xy."""
    x, y = route[0]
    heading = route[1] - route[0]
    yaw = np.arctan2(-heading[0], heading[1])
    v, path = 0.0, []
    driver.reset(seed=0)
    for _ in range(steps):
        info = {"speed_mps": v, "pose": np.array([x, y, 0, 0, 0, yaw])}
        a0, st = driver.act(None, info)
        v = max(0.0, v + DT * (3.0 * a0 if a0 >= 0 else 6.0 * a0))
        phi = st * MAX_STEER
        x += -np.sin(yaw) * v * DT
        y += np.cos(yaw) * v * DT
        yaw += v * np.tan(phi) / L * DT
        path.append((x, y))
    return np.array(path)


def cross_track(path, route):
    d = np.hypot(path[:, None, 0] - route[None, :, 0], path[:, None, 1] - route[None, :, 1])
    return d.min(axis=1)


def test_protocol():
    for d in (
        ConstantSpeedDriver(),
        RecklessDriver(),
        PurePursuitDriver(np.array([[0.0, 0.0], [0.0, 1.0]])),
    ):
        assert isinstance(d, Driver)


def test_constant_speed_converges():
    drv = ConstantSpeedDriver()
    v = 0.0
    for _ in range(200):
        a0, st = drv.act(None, {"speed_mps": v})
        assert st == 0.0
        v = max(0.0, v + DT * 3.0 * a0)
    assert abs(v - 25 / 3.6) < 0.01


def test_reckless_never_brakes():
    drv = RecklessDriver()
    for v in np.linspace(0, 20, 101):
        a0, st = drv.act(None, {"speed_mps": v})
        assert a0 >= 0 and st == 0
        assert (a0 == 1.0) == (v < 25 / 3.6)


def test_pure_pursuit_circle():
    t = np.linspace(0, 2 * np.pi, 721)
    r = 15.0
    route = np.column_stack([r * np.cos(t) - r, r * np.sin(t)])  # left circle from the origin heading +Y
    drv = PurePursuitDriver(route, PurePursuitConfig(closed=True))
    path = bicycle(route, drv, 400)
    err = cross_track(path[50:], route)
    assert err.max() < 0.5


def test_pure_pursuit_s_route():
    y = np.linspace(0, 120, 1201)
    route = np.column_stack([6.0 * np.sin(y / 15.0), y])
    drv = PurePursuitDriver(route)
    path = bicycle(route, drv, 300)
    err = cross_track(path[30:], route)
    assert err.max() < 0.5
    assert path[-1, 1] > 60


def test_deterministic():
    route = np.column_stack([np.zeros(50), np.arange(50.0)])
    a = bicycle(route, PurePursuitDriver(route), 50)
    b = bicycle(route, PurePursuitDriver(route), 50)
    assert np.array_equal(a, b)


def test_errors():
    with pytest.raises(ConfigError):
        PurePursuitDriver(np.zeros((1, 2)))
    with pytest.raises(ConfigError):
        PurePursuitConfig(lookahead_m=0)
    with pytest.raises(ActionError, match="pose"):
        PurePursuitDriver(np.zeros((3, 2))).act(None, {"speed_mps": 0.0})
    with pytest.raises(ActionError, match="speed_mps"):
        RecklessDriver().act(None, {})
