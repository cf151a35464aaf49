import numpy as np
import pytest

from negobs_gym.core.pose import Pose
from negobs_gym.detector import NegativeDetectorConfig, convex_overlap_mask
from negobs_gym.drivers import make_driver
from negobs_gym.envs.scenarios import BrakingEnv, OffroadNavV2Env
from negobs_gym.errors import ConfigError
from negobs_gym.spec import ObservationConfig, apply_overrides, load_scenario

#: OffroadTrack-v0 on its shortest course: the same obstacles, 20-45 m along it instead of 20-105 m,
#: so the car meets them within 50 steps (the detector grid costs ~50 ms a step).
SHORT_COURSE = apply_overrides(load_scenario("offroad_nav_v2"), ["terrain.params.length_m=60"])
#: Braking-v1's scene with the car standing at the start, for 30 s.
STANDING = {"start.speed_mps": 0.0, "episode.time_limit_s": 30.0}


def test_observed_layer_is_the_cells_of_the_frames_returns() -> None:
    env = BrakingEnv(overrides=STANDING)
    env.reset(seed=3)
    env.step(np.array([0.5, 0.0], np.float32))
    perception = env._detector.perception
    layers = perception.observe(timestamp_s=0.2)
    grid = perception.config.grid
    want = np.zeros(grid.shape, dtype=bool)
    row, col, inside = grid.cell_of(perception.points_vehicle()[:, :2])
    want[row[inside], col[inside]] = True
    np.testing.assert_array_equal(layers["observed"], want)
    assert 0.3 < want.mean() < 1.0  # a real frame: much of the grid seen, not all of it
    env.close()


def test_positive_hold_keeps_paper_t_obstacles_on_the_grid_after_the_lux_loses_them() -> None:
    """Same seed and actions: the held grid holds every cell of the per-frame grid, and more once
    an obstacle has left the LUX's view; the rest of the observation is the same."""
    envs = [
        OffroadNavV2Env(
            scenario=SHORT_COURSE,
            overrides={"observation.source": "detector", "observation.positive_hold_s": s},
        )
        for s in (0.0, 2.0)
    ]
    (per_frame, info), (held, _) = (env.reset(seed=1_000_003) for env in envs)
    driver = make_driver("track_planner", envs[0].terrain, planner_sight_m=14.0, planner_horizon_m=30.0)
    seen = extra = 0
    for _ in range(150):
        now, kept = per_frame["grid"][1] > 0, held["grid"][1] > 0
        assert np.array_equal(per_frame["grid"][0], held["grid"][0])  # negative: untouched
        assert np.array_equal(per_frame["state"], held["state"])
        assert not (now & ~kept).any()
        seen += int(now.any())
        extra += int((kept & ~now).any())
        if seen and extra >= 3:
            break
        action = driver.act(per_frame, info)
        per_frame, _, _, _, info = envs[0].step(action)
        held = envs[1].step(action)[0]
    for env in envs:
        env.close()
    assert seen and extra >= 3


@pytest.mark.parametrize("field", ["positive_hold_s", "hazard_hold_s"])
def test_bad_holds_are_refused(field: str) -> None:
    for bad in (-1.0, float("nan"), float("inf"), "2"):
        with pytest.raises(ConfigError, match=field):
            ObservationConfig(**{field: bad})


# slow (end to end): the structure channel is checked by tests/detector/test_structure.py; this
# drives it in the env
@pytest.mark.slow
def test_structure_positive_channel_marks_rocks_and_boxes_on_their_footprint() -> None:
    """``positive_detector="structure"``: every rock or box 6-12 m ahead has a set cell on its pooled
    footprint, and the rest of the observation equals the default (paper T) env's."""
    envs = [
        OffroadNavV2Env(
            scenario=SHORT_COURSE,
            overrides={"observation.source": "detector", "observation.positive_detector": d},
        )
        for d in ("traversable", "structure")
    ]
    (paper_t, info), (structure, _) = (env.reset(seed=1_000_003) for env in envs)
    obs_cfg = envs[1].scenario.observation
    grid, k = obs_cfg.grid, obs_cfg.downsample
    driver = make_driver("track_planner", envs[0].terrain, planner_sight_m=14.0, planner_horizon_m=30.0)
    checked = set()
    for _ in range(60):
        assert np.array_equal(paper_t["grid"][0], structure["grid"][0])
        assert np.array_equal(paper_t["state"], structure["state"])
        pose = Pose.from_array(info["pose"])
        for obstacle in envs[1].terrain.positive_obstacles:
            if obstacle.kind not in ("rock", "box"):
                continue
            corners = np.asarray(obstacle.footprint_xy_m)
            local = pose.to_vehicle(np.c_[corners, np.zeros(len(corners))])[:, :2]
            if 6.0 < local[:, 1].min() < 12.0 and np.abs(local[:, 0]).max() < grid.side_m:
                cells = convex_overlap_mask(local, grid).reshape(grid.rows // k, k, -1, k).any(axis=(1, 3))
                assert (cells & (structure["grid"][1] > 0)).any(), obstacle.obstacle_id
                checked.add(obstacle.obstacle_id)
        action = driver.act(paper_t, info)
        paper_t, _, _, _, info = envs[0].step(action)
        structure = envs[1].step(action)[0]
        if len(checked) == 1:  # the box in view: the filter's positive points are the channel's cells
            hazards = envs[1].hazard_state().positive_obstacles_xy_m
            assert len(hazards) > 0
            cells = grid.occupied(hazards)
            assert cells.sum() == len(hazards)
            assert np.array_equal(
                cells.reshape(grid.rows // k, k, -1, k).any(axis=(1, 3)), structure["grid"][1] > 0
            )
    for env in envs:
        env.close()
    assert len(checked) >= 2  # a box at 37 steps, a rock at 49 on this course


def test_bad_positive_detector_is_refused() -> None:
    with pytest.raises(ConfigError, match="positive_detector"):
        ObservationConfig(positive_detector="lidar")


@pytest.mark.parametrize("hold_s", [0.0, 1.0])
def test_hazard_hold_keeps_the_filters_cells_where_they_were_seen(hold_s: float) -> None:
    """With ``hazard_hold_s`` the filter's points are this frame's cells followed by the earlier
    frames' cells moved into the current vehicle frame; without, this frame's cells only."""
    env = BrakingEnv(overrides={"observation.hazard_hold_s": hold_s})
    env.reset(seed=3)
    assert env._vehicle.config.ins_position_noise_m == 0  # the INS pose is the true pose
    perception = env._detector.perception
    action = np.array([0.3, 0.0], np.float32)
    while not perception.detection.grid.any():
        env.step(action)
    seen_world = env._vehicle.true_pose().to_world(
        np.column_stack([perception.negative_cells_xy_m(), np.zeros(len(perception.negative_cells_xy_m()))])
    )
    env.step(action)
    hazards = env.hazard_state().negative_obstacles_xy_m
    grid = perception.config.grid
    current = grid.cell_centres()[perception.detection.grid]
    assert np.array_equal(hazards[: len(current)], current)
    if hold_s == 0:
        assert len(hazards) == len(current)
    else:
        earlier = env._vehicle.true_pose().to_vehicle(seen_world)[:, :2]
        gaps = np.min(
            np.hypot(*(earlier[:, None, :] - hazards[None, len(current) :, :]).transpose(2, 0, 1)), axis=1
        )
        assert gaps.max() < 1e-6  # every cell seen a frame ago is held where it was
    env.close()


def test_tighten_pairs_moves_the_hazard_cells_to_the_ditch_rim() -> None:
    """Braking-v0's ditch, seen from 20-40 m and approached to ~8 m: with paper N's history the
    nearest hazard cell stays a far ring gap before the rim; with ``tighten_pairs`` (the envs'
    default) it follows the close frames' last ground return. Same seed, same actions."""
    from negobs_gym.safety.corridor import hazard_distance_m

    leads = {}
    for tighten in (False, None):  # None: the default config
        changes = {} if tighten is None else {"observation.tighten_pairs": tighten}
        env = BrakingEnv(overrides={**STANDING, **changes})
        _, info = env.reset(seed=4)
        assert env._detector.perception.negative.config.fusion.tighten_on_match is (tighten is None)
        while info["distance_to_negative_ahead_m"] > 8.0:
            _, _, terminated, truncated, info = env.step(np.array([1.0, 0.0], np.float32))
            assert not (terminated or truncated)
        state = env.hazard_state()
        detected = hazard_distance_m(state.negative_obstacles_xy_m, 0.0, state.wheelbase_m, 1.0)
        leads[tighten] = info["distance_to_negative_ahead_m"] + state.front_length_m - detected
        env.close()
    assert leads[False] > 1.0  # the far frames' edge
    assert -0.1 < leads[None] < 0.6
    assert NegativeDetectorConfig().fusion.tighten_on_match is False  # the detector alone: paper N


def test_tighten_pairs_must_be_a_bool() -> None:
    for bad in ("true", 1, None):
        with pytest.raises(ConfigError, match="tighten_pairs"):
            ObservationConfig(tighten_pairs=bad)


def test_the_lux_sits_on_the_front_bumper() -> None:
    """Default: every LUX return lies ahead of the body's front, the nearest at about where its
    lowest layer (1.2 deg below the 5.03 deg pitch) meets the ground; ``lux_forward_m=2.0``, the
    old mount, casts from 1.7 m farther back; paper N's scans are the same bit for bit."""
    scans = {}
    for forward in (None, 2.0):  # None: the default config
        changes = {} if forward is None else {"observation.lux_forward_m": forward}
        env = BrakingEnv(overrides={**STANDING, **changes})
        env.reset(seed=3)
        scans[forward] = env._detector.perception.scans
        front_m = env._vehicle.config.length_m - env._vehicle.config.rear_overhang_m
        env.close()
    bumper, inside = (scans[k]["lux"] for k in (None, 2.0))
    assert bumper.translation_m[1] - front_m == pytest.approx(0.05)
    assert inside.translation_m[1] == 2.0
    points = {k: s.points_vehicle[np.isfinite(s.ranges_m)] for k, s in ((None, bumper), (2.0, inside))}
    assert len(points[None]) > 100 and points[None][:, 1].min() > front_m
    reach_m = np.hypot(*(points[None][:, :2] - bumper.translation_m[:2]).T)  # from the sensor, level
    lowest_layer_m = 0.65 / np.tan(np.radians(5.03 + 1.2))
    assert reach_m.min() == pytest.approx(lowest_layer_m, abs=0.5)  # a rough track
    assert np.median(points[None][:, 1]) - np.median(points[2.0][:, 1]) == pytest.approx(1.7, abs=0.3)
    for name in scans[None]:
        if name != "lux":
            assert np.array_equal(scans[None][name].ranges_m, scans[2.0][name].ranges_m, equal_nan=True)


def test_lux_forward_m_must_be_finite() -> None:
    for bad in (float("nan"), float("inf"), "3.7", None, True):
        with pytest.raises(ConfigError, match="lux_forward_m"):
            ObservationConfig(lux_forward_m=bad)


def test_lux_ego_motion_reaches_paper_t_and_must_be_a_bool() -> None:
    for flag in (False, True):
        env = BrakingEnv(overrides={**STANDING, "observation.lux_ego_motion": flag})
        env.reset(seed=3)
        env.step(np.array([0.5, 0.0], dtype=np.float32))
        assert env._detector.perception.traversable.config.kalman_ego_motion is flag
        env.close()
    for bad in ("true", 1, None):
        with pytest.raises(ConfigError, match="lux_ego_motion"):
            ObservationConfig(lux_ego_motion=bad)


def test_raycast_fast_terrain_reaches_the_caster_and_must_be_a_bool() -> None:
    """The flag picks the static scene's triangle test; the observations agree either way (the
    two tests' ranges differ by float32 rounding, far below a 20 cm cell)."""
    from negobs_gym.sensors.raycast.embree_packets import PacketScene, RepairedScene, packets_available

    if not packets_available():
        pytest.skip("embreex's libembree4 not found: the fast terrain test needs the packet path")
    observations = []
    for flag, scene in ((False, PacketScene), (True, RepairedScene)):
        env = BrakingEnv(overrides={**STANDING, "observation.raycast_fast_terrain": flag})
        env.reset(seed=3)
        assert isinstance(env._detector.perception._caster._static._packets, scene)
        observations.append(env.step(np.array([0.5, 0.0], dtype=np.float32))[0])
        env.close()
    np.testing.assert_array_equal(observations[0]["grid"], observations[1]["grid"])
    for bad in ("false", 0, None):
        with pytest.raises(ConfigError, match="raycast_fast_terrain"):
            ObservationConfig(raycast_fast_terrain=bad)


def _blas_threads_of_worker_envs(out) -> None:
    """In a child process: the BLAS thread counts before any env, after a detector-grid env's reset
    with ``worker_blas_threads=None``, then after one's with ``1``; the BLAS first set to 2 threads
    (its default on 2 cores, set so on any machine). ``None`` first: a pin stays for the process."""
    from threadpoolctl import threadpool_info, threadpool_limits

    def counts() -> list[int]:
        return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]

    threadpool_limits(limits=2, user_api="blas")
    seen = [counts()]
    for threads in (None, 1):
        env = BrakingEnv(overrides={**STANDING, "observation.worker_blas_threads": threads})
        env.reset(seed=3)
        seen.append(counts())
        env.close()
    out.put(seen)


def test_worker_processes_pin_their_blas_as_configured() -> None:
    """One spawned child (one start-up) checks both settings: None leaves the BLAS alone, 1 pins it."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    out = ctx.Queue()
    child = ctx.Process(target=_blas_threads_of_worker_envs, args=(out,))
    child.start()
    before, unpinned, pinned = out.get(timeout=120)
    child.join(timeout=30)
    assert child.exitcode == 0
    assert before and before == [2] * len(before)  # numpy's and scipy's BLAS are there, at 2
    assert unpinned == before
    assert pinned == [1] * len(before)


def test_worker_blas_threads_rejects_bad_values() -> None:
    for bad in (0, 65, 1.0, "1", True):
        with pytest.raises(ConfigError, match="worker_blas_threads"):
            ObservationConfig(worker_blas_threads=bad)
