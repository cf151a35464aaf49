"""rgb_array frames: layout, LiDAR points, detected outlines, safety-filter state, RecordVideo."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import negobs_gym  # noqa: F401 - registers the envs
from negobs_gym.core.pose import Pose
from negobs_gym.envs import rendering
from negobs_gym.envs.rendering import RenderConfig, frame_shape, render_frame
from negobs_gym.errors import ConfigError
from negobs_gym.safety import BrakingSafetyFilter, Corridor, SafetyDecision
from negobs_gym.sim import presets
from negobs_gym.spec import ObservationConfig

OBS = ObservationConfig()


@pytest.fixture(scope="module")
def terrain():
    return presets.braking_track(ditch_distance_m=20.0, seed=0, rough=False)


def _decision(
    vetoed: bool, hazard_distance_m: float, braking_distance_m: float, corridor: Corridor | None = None
) -> SafetyDecision:
    action = np.zeros(2, np.float32)
    return SafetyDecision(
        vetoed=vetoed,
        hazard_distance_m=hazard_distance_m,
        braking_distance_m=braking_distance_m,
        speed_mps=0.0,
        safe_speed_mps=0.0,
        original_action=action,
        applied_action=action,
        perception_age_s=0.0,
        perception_stale=False,
        corridor=corridor,
    )


def _frame(terrain, **kwargs) -> np.ndarray:
    pose = Pose(x=0.0, y=0.0, yaw=0.0)
    return render_frame(terrain, pose, np.array([[0.0, -1.0], [0.0, 0.0]]), None, OBS, **kwargs)


def _local(frame: np.ndarray) -> np.ndarray:
    return frame[:, RenderConfig().overview_width_px :]


def _local_px(x_m: float, y_m: float) -> tuple[int, int]:
    """Pixel of a vehicle-frame point in the local panel (same mapping as the renderer)."""
    h, w = RenderConfig().height_px, frame_shape(OBS)[1] - RenderConfig().overview_width_px
    g = OBS.grid
    return int((g.ahead_m - y_m) * h / (g.ahead_m + g.back_m)), int((x_m + g.side_m) * w / (2 * g.side_m))


def test_frame_shape_is_even_and_as_announced(terrain) -> None:
    frame = _frame(terrain)
    assert frame.shape == frame_shape(OBS) and frame.dtype == np.uint8
    assert frame.shape[0] % 2 == 0 and frame.shape[1] % 2 == 0  # yuv420p video needs even sizes


def test_vetoed_and_passing_steps_differ_in_the_border_only_there(terrain) -> None:
    passed = _local(_frame(terrain, safety=_decision(False, 12.0, 8.0)))
    vetoed = _local(_frame(terrain, safety=_decision(True, 12.0, 8.0)))
    none = _local(_frame(terrain, safety=None))
    b = RenderConfig().border_px
    for img, colour in (
        (passed, rendering.BORDER_PASS),
        (vetoed, rendering.BORDER_VETO),
        (none, rendering.BORDER_NONE),
    ):
        for edge in (img[:b], img[-b:], img[:, :b], img[:, -b:]):
            assert np.all(edge == colour)
    inner = (slice(b, -b), slice(b, -b))
    assert np.array_equal(passed[inner], vetoed[inner])  # the decision shows in the border


def test_hazard_and_braking_marks_are_drawn_at_their_distances(terrain) -> None:
    frame = _local(_frame(terrain, safety=_decision(True, 12.0, 6.0)))
    for d, colour in ((12.0, rendering.HAZARD_MARK), (6.0, rendering.BRAKING_MARK)):
        row, col = _local_px(0.0, d)
        assert np.array_equal(frame[row, col], colour)
        assert not np.array_equal(frame[_local_px(0.0, d + 1.5)], colour)
    clear = _local(_frame(terrain, safety=_decision(False, np.inf, 6.0)))
    assert not np.any(np.all(clear == rendering.HAZARD_MARK, axis=-1))  # no hazard: no d mark


def test_marks_are_laid_out_from_the_pose_where_the_filter_decided(terrain) -> None:
    decided_at = Pose(x=0.0, y=-1.5, yaw=0.0)  # the step before: 1.5 m behind the current pose
    frame = _local(_frame(terrain, safety=_decision(True, 12.0, 6.0), decision_pose=decided_at))
    for d, colour in ((12.0, rendering.HAZARD_MARK), (6.0, rendering.BRAKING_MARK)):
        assert np.array_equal(frame[_local_px(0.0, d - 1.5)], colour)  # where the filter measured
        assert not np.array_equal(frame[_local_px(0.0, d)], colour)


def test_in_a_turn_the_marks_and_corridor_follow_the_arc(terrain) -> None:
    corridor = Corridor(steer_rad=0.15, wheelbase_m=2.8, half_width_m=1.2, front_length_m=3.65)
    frame = _local(_frame(terrain, safety=_decision(True, 12.0, 9.0, corridor)))
    for d, colour in ((12.0, rendering.HAZARD_MARK), (9.0, rendering.BRAKING_MARK)):
        x, y = corridor.reached_at_xy_m(d).mean(axis=0)
        assert x < -1.5  # bent well to the left of straight ahead
        assert np.array_equal(frame[_local_px(x, y)], colour)
        assert not np.array_equal(frame[_local_px(0.0, d)], colour)  # not drawn straight ahead
    inner, outer = corridor.sides_xy_m(10.0, samples=5)
    for x, y in (inner[2], outer[3]):
        assert np.array_equal(frame[_local_px(x, y)], rendering.CORRIDOR)


def test_lidar_points_appear_where_the_returns_are(terrain) -> None:
    xs, ys = np.meshgrid(np.linspace(-4.0, 4.0, 9), np.linspace(5.0, 17.0, 7))  # clear of vehicle and ditch
    pts = np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, -0.8)], axis=1)  # a pit floor: blue end
    without = _local(_frame(terrain))
    with_pts = _local(_frame(terrain, points_vehicle_m=pts))
    changed = np.any(with_pts != without, axis=-1)
    assert 0 < changed.sum() <= len(pts)
    floor = rendering._height_colours(np.array([-0.8]), RenderConfig().point_z_range_m)[0]
    for x, y, _ in pts:
        assert np.array_equal(with_pts[_local_px(x, y)], floor)


def test_points_are_subsampled_and_non_finite_rows_skipped(terrain) -> None:
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-6, 6, 20000), rng.uniform(-3, 25, 20000), rng.uniform(-1, 1, 20000)])
    pts[::7] = np.nan
    cfg = RenderConfig(max_points=50)
    without = _local(_frame(terrain, config=cfg))
    with_pts = _local(_frame(terrain, points_vehicle_m=pts, config=cfg))
    assert 0 < np.any(with_pts != without, axis=-1).sum() <= 50


def test_detected_outlines_are_drawn(terrain) -> None:
    square = np.array([[-1.0, 8.0], [1.0, 8.0], [1.0, 9.0], [-1.0, 9.0]])
    frame = _local(_frame(terrain, detected_outlines_m=[square]))
    assert np.array_equal(frame[_local_px(0.0, 8.0)], rendering.DETECTED_OUTLINE)
    assert not np.any(np.all(_local(_frame(terrain)) == rendering.DETECTED_OUTLINE, axis=-1))


def test_bad_inputs_are_refused(terrain) -> None:
    with pytest.raises(ConfigError, match=r"^grid: must have the observation shape"):  # a ValueError too
        render_frame(terrain, Pose(), np.zeros((1, 2)), np.zeros((4, 3, 3), np.uint8), OBS)
    with pytest.raises(ConfigError, match="height_px"):
        RenderConfig(height_px=481)
    with pytest.raises(ConfigError, match="point_z_range_m"):
        RenderConfig(point_z_range_m=(1.0, 1.0))


def test_env_frames_keep_their_shape_and_show_the_filter_state() -> None:
    env = BrakingSafetyFilter(gym.make("negobs_gym/Braking-v0", render_mode="rgb_array"))
    env.reset(seed=0)
    shape = frame_shape(env.unwrapped.scenario.observation)
    b = RenderConfig().border_px
    first = env.render()
    assert first.shape == shape and np.all(_local(first)[:b] == rendering.BORDER_NONE)  # no decision yet
    colours = []
    for _ in range(40):  # full throttle towards the ditch until the filter vetoes
        _, _, term, trunc, info = env.step(np.array([1.0, 0.0], np.float32))
        frame = env.render()
        assert frame.shape == shape
        colours.append(tuple(_local(frame)[0, 0]))
        assert colours[-1] == (rendering.BORDER_VETO if info["safety"]["vetoed"] else rendering.BORDER_PASS)
        # the env stamps the hazard points with the time of its last LiDAR frame: fresh every step
        assert info["safety"]["perception_age_s"] == 0.0 and not info["safety"]["perception_stale"]
        if info["safety"]["vetoed"] or term or trunc:
            break
    assert rendering.BORDER_PASS in colours and colours[-1] == rendering.BORDER_VETO
    env.unwrapped.step(np.array([-1.0, 0.0], np.float32))  # a step no filter decided
    assert tuple(_local(env.render())[0, 0]) == rendering.BORDER_NONE
    env.close()


def test_env_frame_draws_the_last_lidar_frame() -> None:
    env = gym.make("negobs_gym/Braking-v0", render_mode="rgb_array")
    env.reset(seed=1)
    perception = env.unwrapped.perception
    assert len(perception.points_vehicle()) > 0
    with_points = env.render()
    perception.points_vehicle = lambda: np.empty((0, 3))
    assert np.any(_local(with_points) != _local(env.render()))
    env.close()


def test_render_is_none_without_a_render_mode() -> None:
    env = gym.make("negobs_gym/Braking-v0")
    env.reset(seed=0)
    assert env.render() is None
    env.close()


def test_bad_render_mode_is_refused() -> None:
    from negobs_gym.envs.scenarios import BrakingEnv

    with pytest.raises(ValueError, match="render_mode"):
        BrakingEnv(render_mode="ascii")


def test_record_video_writes_a_non_empty_file(tmp_path) -> None:
    pytest.importorskip("moviepy")
    env = gym.make("negobs_gym/Braking-v0", render_mode="rgb_array")
    env = gym.wrappers.RecordVideo(
        BrakingSafetyFilter(env), str(tmp_path / "videos"), episode_trigger=lambda _: True
    )
    env.reset(seed=0)
    for _ in range(5):
        env.step(np.array([0.5, 0.0], np.float32))
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 1000


def test_a_counting_grid_draws_the_cells_a_maximum_draws() -> None:
    """The local panel shows the cells that hold anything: counting changes the values, not the frame."""
    frames = []
    for pooling in ("max", "count"):
        # the shortest winding course (60 m): a world builds ~4x faster
        changes = {
            "observation.source": "oracle",
            "observation.pooling": pooling,
            "terrain.params.length_m": 60.0,
        }
        env = gym.make("negobs_gym/OffroadTrack-v0", render_mode="rgb_array", overrides=changes)
        obs, _ = env.reset(seed=4)
        for _ in range(80):  # drive until obstacles are in sight (the same step for both)
            obs, *_ = env.step(np.array([0.6, 0.0], np.float32))
            if np.count_nonzero(obs["grid"]) >= 3:
                break
        frames.append((obs["grid"], env.render()))
        env.close()
    (most, frame_max), (count, frame_count) = frames
    assert count.max() > 1 and np.array_equal(most, count > 0)  # obstacles in sight, counted
    np.testing.assert_array_equal(frame_max, frame_count)


def test_a_caption_is_written_at_the_top_left_of_the_overview_only(terrain) -> None:
    plain = _frame(terrain)
    captioned = _frame(terrain, caption=["t   1.0 s   25.0 km/h", "throttle +1.00 steer +0.00"])
    changed = np.argwhere(np.any(plain != captioned, axis=-1))
    assert len(changed) > 0
    assert changed[:, 0].max() < 40 and changed[:, 1].max() < RenderConfig().overview_width_px
    box = captioned[1, 1]
    assert np.array_equal(box, rendering.CAPTION_BOX)
    text = np.all(captioned > 180, axis=-1) & np.any(plain != captioned, axis=-1)
    assert text.sum() > 50  # the letters: light (anti-aliased) pixels the caption put there
    off = _frame(terrain, caption=["t 1.0 s"], config=RenderConfig(caption=False))
    assert np.array_equal(off, plain)
    with pytest.raises(ConfigError, match="caption"):
        RenderConfig(caption="yes")


def test_caption_lines_name_time_speed_action_and_the_filters_distances() -> None:
    assert rendering.caption_lines(0.0, 0.0, None, None) == ["t   0.0 s    0.0 km/h"]
    assert rendering.caption_lines(0.0, -0.001, None, None) == ["t   0.0 s    0.0 km/h"]  # not -0.0
    lines = rendering.caption_lines(4.2, 6.944, np.array([0.5, -0.25]), _decision(True, 9.75, 10.5))
    assert lines == ["t   4.2 s   25.0 km/h", "throttle +0.50 steer -0.25", "d 9.8 m  R 10.5 m  VETO"]
    assert rendering.caption_lines(1.0, 1.0, None, _decision(False, np.inf, 2.0))[1] == "d clear  R 2.0 m"


def test_env_frames_carry_the_caption() -> None:
    frames = {}
    for caption in (True, False):
        env = gym.make("negobs_gym/Braking-v1", render_mode="rgb_array")
        spec = env.unwrapped.scenario
        env.unwrapped.scenario = dataclasses.replace(spec, render=RenderConfig(caption=caption))
        env.reset(seed=0)
        env.step(np.array([0.5, 0.2], np.float32))
        frames[caption] = env.render()
        env.close()
    differ = np.argwhere(np.any(frames[True] != frames[False], axis=-1))
    assert len(differ) > 0 and differ[:, 0].max() < 40  # the caption box, and nothing else
