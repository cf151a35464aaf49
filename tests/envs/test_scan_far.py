"""``ObservationConfig.scan_far_from_m``: between frames, the grid's far part cast and detected."""

import numpy as np
import pytest

from negobs_gym.core.grid import carry_layer
from negobs_gym.detector.fusion import in_box
from negobs_gym.envs.scenarios import BrakingEnv
from negobs_gym.errors import ConfigError
from negobs_gym.spec import CHANNELS, ObservationConfig

COAST = np.array([0.0, 0.0], np.float32)
FAR_M = 12.0


def _env(scan_every: int, render_mode: str | None = None, **observation) -> BrakingEnv:
    """Braking-v0 at 25 km/h from the start, full-resolution grid."""
    settings = {"scan_every": scan_every, "downsample": 1, **observation}
    changes = {f"observation.{key}": value for key, value in settings.items()}
    return BrakingEnv(overrides={"episode.time_limit_s": 30.0, **changes}, render_mode=render_mode)


def _returns_in(scan, box) -> np.ndarray:
    """The scan's returns inside the vehicle-frame box, (N, 3), sorted."""
    points = scan.points_vehicle[np.isfinite(scan.ranges_m)]
    points = points[in_box(points, box)]
    return points[np.lexsort(points.T[::-1])]


def test_the_far_part_is_cast_and_detected_as_an_every_step_run_does_there() -> None:
    """k = 2, far part from 12 m, against a frame every step (same seed and actions), driving at
    the 1 m ditch: at each step between frames the returns beyond 12 m are the every-step scan's
    (same rays, same ranges); paper N's pairs of that part are the every-step frame's; its grid
    marks the ditch as the every-step grid does; paper T ran on the LUX; the near part of
    ``observed`` is the last frame's moved; the hazards' age is the whole frame's."""
    every, pair = _env(1), _env(2, scan_far_from_m=FAR_M)
    every.reset(seed=1)
    obs, _ = pair.reset(seed=1)
    observed = CHANNELS.index("observed")
    frame_observed, frame_pose = obs["grid"][observed], pair.perception.pose
    box = (-6.4, 6.4, FAR_M, 25.6)
    assert pair.perception.far_region_xy_m == box and every.perception.far_region_xy_m is None
    assert ObservationConfig(scan_far_from_m=FAR_M).far_region_xy_m is None  # no steps between frames
    marked = 0
    for step in range(1, 41):
        every.step(COAST)
        obs, *_ = pair.step(COAST)
        p, e = pair.perception, every.perception
        if step % 2 == 0:
            frame_observed, frame_pose = obs["grid"][observed], p.pose
            continue
        assert pair.hazard_state().perception_age_s == pytest.approx(0.1)
        for name, scan in p.far_scans.items():
            np.testing.assert_array_equal(_returns_in(scan, box), _returns_in(e.scans[name], box))
        for name, pairs in p.detection.frame_pairs.items():
            native = e.detection.frame_pairs[name]
            inside = in_box(native.a_m, box) & in_box(native.b_m, box)
            np.testing.assert_array_equal(np.sort(pairs.a_m, axis=0), np.sort(native.a_m[inside], axis=0))
        if e.detection.grid.any():
            both = (p.detection.grid & e.detection.grid).sum()
            assert both >= 0.9 * max(p.detection.grid.sum(), e.detection.grid.sum())
            marked += 1
        np.testing.assert_array_equal(obs["grid"][CHANNELS.index("negative")], p.detection.grid)
        np.testing.assert_array_equal(obs["grid"][CHANNELS.index("traversable")], p.region.traversable)
        carried = carry_layer(frame_observed, p.config.grid.carry_index(frame_pose, p.pose))
        assert np.all(obs["grid"][observed] >= carried)
    assert marked >= 5  # the ditch was in the grid on several steps between frames
    every.close()
    pair.close()


def test_the_rendered_returns_beyond_the_far_edge_are_the_steps_own() -> None:
    env = _env(2, render_mode="rgb_array", scan_far_from_m=FAR_M)
    env.reset(seed=0)
    env.step(COAST)  # between frames
    perception = env.perception
    points = perception.points_vehicle()
    box = perception.far_region_xy_m
    far = np.concatenate([s.points_vehicle[np.isfinite(s.ranges_m)] for s in perception.far_scans.values()])
    np.testing.assert_array_equal(points[in_box(points, box)], far[in_box(far, box)])
    assert (~in_box(points, box)).sum() > 1000  # the near part: the last frame's returns
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3
    env.close()


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), True, "12", -3.2, 25.6, 40.0])
def test_bad_far_distances_are_refused(bad) -> None:
    with pytest.raises(ConfigError, match="scan_far_from_m"):
        ObservationConfig(scan_every=3, scan_far_from_m=bad)
