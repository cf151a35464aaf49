"""The corridor along a planned path against the arc corridor it generalises."""

from __future__ import annotations

import math

import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.safety.corridor import hazard_distance_m
from negobs_gym.safety.path_corridor import path_hazard_distance_m, resample_path

WHEELBASE, HALF_WIDTH, FRONT = 2.8, 1.1, 3.7


def _arc_path(steer_rad: float, length_m: float = 40.0) -> np.ndarray:
    """The rear-axle circle of steering ``steer_rad`` (left positive, towards -X), every 5 cm."""
    s = np.arange(0.05, length_m, 0.05)
    kappa = math.tan(steer_rad) / WHEELBASE
    if abs(kappa) < 1e-12:
        return np.column_stack([np.zeros_like(s), s])
    return np.column_stack([-(1.0 - np.cos(kappa * s)) / kappa, np.sin(kappa * s) / kappa])


def test_a_straight_plan_is_the_straight_corridor_exactly() -> None:
    rng = np.random.default_rng(0)
    points = rng.uniform([-4.0, -2.0], [4.0, 30.0], size=(500, 2))
    plan = np.array([[0.0, 5.0], [0.0, 12.0]])  # extended straight on past its end
    for k in range(50):
        subset = points[k * 10 : (k + 1) * 10]
        want = hazard_distance_m(subset, 0.0, WHEELBASE, HALF_WIDTH, FRONT)
        assert path_hazard_distance_m(subset, plan, HALF_WIDTH, FRONT) == pytest.approx(want, abs=1e-9)


@pytest.mark.parametrize("steer_deg", [-30.0, -12.0, 5.0, 20.0, 35.0])
def test_an_arc_plan_agrees_with_the_arc_corridor(steer_deg: float) -> None:
    """Points well inside or outside the ring agree on being in it and, inside, on where they are
    reached (the radial projection: abreast of the rear axle), within 3 cm (the 10 cm sampling)."""
    steer = math.radians(steer_deg)
    rng = np.random.default_rng(int(steer_deg) + 100)
    radius = WHEELBASE / math.tan(abs(steer))
    plan = _arc_path(steer)
    compared = inside = 0
    for point in rng.uniform([-12.0, 0.5], [12.0, 14.0], size=(400, 2)):
        x = point[0] if steer > 0 else -point[0]
        r = math.hypot(x + radius, point[1])
        outer = math.hypot(radius + HALF_WIDTH, FRONT)
        if min(abs(r - (radius - HALF_WIDTH)), abs(r - (radius + HALF_WIDTH)), abs(r - outer)) < 0.1:
            continue  # at the ring's edges the footprint sampling decides
        theta = math.atan2(point[1], x + radius) % (2 * math.pi)
        if theta > math.pi / 2:  # beyond a quarter turn the 40 m plan and the ring part ways
            continue
        arc = hazard_distance_m(point[None], steer, WHEELBASE, HALF_WIDTH, FRONT)
        if 30.0 < arc < math.inf:  # beside the outer rear: reached a turn later, past the plan
            continue
        planned = path_hazard_distance_m(point[None], plan, HALF_WIDTH, FRONT)
        compared += 1
        assert np.isfinite(arc) == np.isfinite(planned), (point, arc, planned)
        if np.isfinite(arc):
            inside += 1
            assert planned == pytest.approx(arc, abs=0.03), (point, arc, planned)
    assert compared > 150 and inside > 20


def test_a_plan_round_a_pit_clears_what_the_arc_of_the_moment_runs_into() -> None:
    """Mid-swerve at full left lock: the arc of the moment crosses a pit 6 m ahead on the left;
    the plan straightens out and passes right of it."""
    pit = np.array([[x, y] for x in np.arange(-5.0, -3.4, 0.2) for y in np.arange(5.0, 7.0, 0.2)])
    steer = math.radians(35.0)
    assert np.isfinite(hazard_distance_m(pit, steer, WHEELBASE, HALF_WIDTH, FRONT))
    s = np.arange(0.1, 1.05, 0.1)  # 1 m more of the left bend, then straight on (14 deg left)
    kappa = math.tan(steer) / WHEELBASE
    bend = np.column_stack([-(1.0 - np.cos(kappa * s)) / kappa, np.sin(kappa * s) / kappa])
    heading = kappa * s[-1]
    straight = bend[-1] + np.outer(np.arange(0.5, 20.0, 0.5), [-math.sin(heading), math.cos(heading)])
    plan = np.vstack([bend, straight])
    assert path_hazard_distance_m(pit, plan, HALF_WIDTH, FRONT) == math.inf
    # a pit on that plan is reached along it, where the rear axle comes abreast of it
    on_plan = straight[8] + np.array([[0.0, 0.0], [0.3, 0.3]])
    assert path_hazard_distance_m(on_plan, plan, HALF_WIDTH, FRONT) == pytest.approx(1.0 + 4.5, abs=0.05)


def test_points_behind_the_rear_axle_and_empty_input() -> None:
    plan = np.array([[0.0, 10.0]])
    assert path_hazard_distance_m(np.array([[0.0, -0.05], [0.5, -1.0]]), plan, HALF_WIDTH, FRONT) == math.inf
    assert path_hazard_distance_m(np.zeros((0, 2)), plan, HALF_WIDTH, FRONT) == math.inf
    assert path_hazard_distance_m(np.array([[0.0, 0.0]]), plan, HALF_WIDTH, FRONT) == 0.0


def test_resampling_runs_from_the_origin_and_extends_the_last_segment() -> None:
    stations, positions, tangents = resample_path(np.array([[0.0, 1.0], [1.0, 1.0]]), 0.1, 5.0)
    assert stations[0] == 0.0 and stations[-1] == pytest.approx(5.0)
    np.testing.assert_allclose(positions[0], [0.0, 0.0])
    np.testing.assert_allclose(positions[-1], [4.0, 1.0], atol=1e-9)  # 1 m up, then right to 5 m
    np.testing.assert_allclose(tangents[-1], [1.0, 0.0])
    _, positions, _ = resample_path(np.zeros((3, 2)), 0.5, 2.0)  # no direction: straight ahead
    np.testing.assert_allclose(positions[-1], [0.0, 2.0])


@pytest.mark.parametrize("bad", [np.array([[0.0, np.nan]]), np.zeros((3, 3)), np.zeros(4)])
def test_a_bad_plan_is_named(bad: np.ndarray) -> None:
    with pytest.raises(ConfigError, match="path_xy_m"):
        path_hazard_distance_m(np.array([[0.0, 5.0]]), bad, HALF_WIDTH, FRONT)
