"""TraversableConfig: paper defaults and validation naming the field."""

from __future__ import annotations

import math

import pytest

from negobs_gym.detector.traversable import TraversableConfig
from negobs_gym.errors import ConfigError


def test_paper_defaults() -> None:
    cfg = TraversableConfig()
    assert cfg.n_layers == 4
    assert cfg.boundary_layers == (0, 1, 2)  # lower three layers (§3.1)
    assert cfg.obstacle_layers == (1, 2)  # middle two layers (§3.3)
    assert cfg.max_steering_deg == 35.0 and cfg.wheelbase_m == 2.8
    assert cfg.rear_turn_radius_m == pytest.approx(2.8 / math.tan(math.radians(35)), rel=1e-12)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("d_t1_m", 0.0),
        ("d_t2_m", float("nan")),
        ("tear_distance_m", -1.0),
        ("kalman_measurement_var_m2", 0.0),
        ("kalman_process_var_m2", float("inf")),
        ("max_steering_deg", 90.0),
        ("max_steering_deg", 0.0),
        ("clean_run_points", 0),
        ("clean_run_points", 2.5),
        ("boundary_layers", ()),
        ("boundary_layers", (0, 4)),
        ("obstacle_layers", (0, 1)),
        ("hough_max_tilt_deg", 95.0),
        ("safety_margin_m", -0.1),
        ("vehicle_width_m", 0.0),
        ("neighbour_columns", -1),
        ("curve_refits", -1),
        ("curve_refits", 1.5),
        ("curve_min_points", 2),
        ("max_range_m", 0.0),
    ],
)
def test_invalid_values_name_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=field) as err:
        TraversableConfig(**{field: value})
    assert err.value.field == field


def test_frozen() -> None:
    cfg = TraversableConfig()
    with pytest.raises(AttributeError):
        cfg.d_t1_m = 1.0  # type: ignore[misc]
