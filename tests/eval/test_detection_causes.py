"""False-alarm causes: the terrain class under a detection, the cause table and the worst frames."""

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.errors import ConfigError, GeometryError
from negobs_gym.eval.detection import DetectionEvalConfig, match_frame
from negobs_gym.eval.detection_campaign import (
    FALSE_ALARM_COLUMNS,
    FRAME_COLUMNS,
    OBSTACLE_COLUMNS,
    SENSOR_MODES,
    cause_rows,
    summarize,
    worst_frames,
)
from negobs_gym.eval.detection_causes import CAUSES, CauseConfig, TerrainClassifier


def _terrain(roughness=None):
    from negobs_gym.sim.carving import PositiveObstacleSpec
    from negobs_gym.sim.terrain import BorderConfig, RoughnessConfig, TerrainConfig, generate_terrain

    config = TerrainConfig(
        length_m=40.0,
        corridor_width_m=24.0,
        roughness=roughness or RoughnessConfig.flat(),
        right_border=BorderConfig(kind="dropoff"),
        left_border=BorderConfig(kind="verge"),
        positive_obstacles=(PositiveObstacleSpec(kind="rock", station_m=20.0, lateral_m=-4.0),),
    )
    return generate_terrain(config, 0)


def _square(terrain, station, lateral, half=0.3):
    (x, y), _ = terrain.track.pose_at(station, lateral)
    return np.array([[x - half, y - half], [x + half, y - half], [x + half, y + half], [x - half, y + half]])


def test_classes_from_the_terrain_record():
    terrain = _terrain()
    classify = TerrainClassifier(terrain).classify
    assert classify(_square(terrain, 10.0, 0.5)) == "track"
    assert classify(_square(terrain, 10.0, 3.8)) == "verge"  # right verge: 3 to 4.5 m
    assert classify(_square(terrain, 10.0, 6.0)) == "drop-off"  # beyond the right verge
    assert classify(_square(terrain, 20.0, -5.0)) == "beside rock"  # 1 m past the rock
    assert classify(_square(terrain, 10.0, -8.0)) == "other"  # flat ground past the left verge


def test_rough_ground_needs_relief_under_the_outline():
    from negobs_gym.sim.terrain import RoughnessConfig

    rough = _terrain(RoughnessConfig(bump_amplitude_m=0.4))
    labels = {
        TerrainClassifier(rough).classify(_square(rough, s, -9.0, 0.5)) for s in np.arange(5.0, 35.0, 2.0)
    }
    assert "rough ground" in labels
    assert labels <= {"rough ground", "other"}
    strict = TerrainClassifier(rough, CauseConfig(rough_relief_m=10.0))
    assert strict.classify(_square(rough, 10.0, -9.0, 0.5)) == "other"


def test_bad_input():
    terrain = _terrain()
    with pytest.raises(GeometryError):
        TerrainClassifier(terrain).classify(np.array([[np.nan, 0.0]]))
    with pytest.raises(ConfigError, match="positive_margin_m"):
        CauseConfig(positive_margin_m=-1.0)


def test_match_frame_names_its_false_alarms_and_forgives_an_overlap_past_the_grid_edge():
    grid = GridSpec()
    truth = np.array([[1.5, -6.0], [3.6, -6.0], [3.6, -5.3], [1.5, -5.3]])  # just behind the grid
    past_edge = np.array([[1.4, -7.0], [3.2, -7.0], [3.2, -4.9], [1.4, -4.9]])  # one row inside
    lone = np.array([[-5.0, 10.0], [-4.0, 10.0], [-4.0, 11.0], [-5.0, 11.0]])
    far = np.array([[50.0, 50.0], [51.0, 50.0], [51.0, 51.0]])  # outside: not judged
    match = match_frame([far, past_edge, lone], [truth], grid)
    assert match.false_alarms == 1 and list(match.false_alarm_index) == [2]
    before = match_frame([far, past_edge, lone], [truth], grid, DetectionEvalConfig(edge_margin_m=0.0))
    assert before.false_alarms == 2 and list(before.false_alarm_index) == [1, 2]


def _write(path, header, rows):
    path.write_text("\n".join([",".join(header), *(",".join(map(str, r)) for r in rows)]) + "\n")


def test_cause_table_and_worst_frames_from_the_csvs(tmp_path):
    frames = []
    for frame in range(3):
        counts = [0] * (3 * len(SENSOR_MODES))
        frames.append(["seed00000", 0, frame, 5.0, 0.5, 0.0, *counts])
    fa = [
        ["seed00000", 0, 1, "fused", "rough ground", 0, 5.0, 10.0, 11.2],
        ["seed00000", 0, 1, "hdl64", "rough ground", 0, 5.0, 10.0, 11.2],
        ["seed00000", 0, 2, "fused", "beside mound", 0, -4.0, 8.0, 8.9],
        ["seed00000", 0, 2, "fused", "track", 1, 1.0, 8.0, 8.1],
    ]
    _write(tmp_path / "frames.csv", FRAME_COLUMNS, frames)
    _write(tmp_path / "obstacles.csv", OBSTACLE_COLUMNS, [])
    _write(tmp_path / "fa.csv", FALSE_ALARM_COLUMNS, fa)
    summary = summarize(
        tmp_path / "obstacles.csv", tmp_path / "frames.csv", DetectionEvalConfig(), tmp_path / "fa.csv"
    )
    assert summary.false_alarm_causes["fused"] == {
        **dict.fromkeys(CAUSES, 0),
        "rough ground": 1,
        "beside mound": 1,
        "track": 1,
    }
    assert summary.false_alarm_causes["hdl32"] == dict.fromkeys(CAUSES, 0)
    rows = {r[0]: r for r in cause_rows(summary)}
    assert rows["rough ground"][1:3] == [1, pytest.approx(1 / 0.0015)]  # count, per km (1.5 m driven)
    assert worst_frames(tmp_path / "fa.csv", 5) == [(0, 2, 2), (0, 1, 1)]
    assert worst_frames(tmp_path / "fa.csv", 1, mode="hdl64") == [(0, 1, 1)]
