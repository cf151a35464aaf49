"""Surveyed negative obstacles of a recorded drive and their recall (negobs_gym.eval.recorded); end to
end through ``negobs detect --truth`` in tests/cli/test_detect_truth.py."""

import numpy as np
import pytest

from negobs_gym.core.grid import GridSpec
from negobs_gym.errors import ConfigError
from negobs_gym.eval.recorded import RecordedRecall, SurveyedObstacle, read_surveyed_obstacles


def test_a_survey_is_checked_and_a_standing_drive_faces_x(tmp_path):
    path = tmp_path / "bad.json"
    for content, message in (
        ("[1, 2]", "wants {"),
        ('{"negative_obstacles": [{"name": "a", "outline_xy_m": [[0, 0], [1, 0]]}]}', r"\(a\): outline_xy_m"),
        ('{"negative_obstacles": [{"outline": []}]}', "no outline_xy_m"),
        ("{", "not a readable JSON file"),
    ):
        path.write_text(content)
        with pytest.raises(ConfigError, match=message):
            read_surveyed_obstacles(path)
    # without poses the outline is in the standing vehicle's ROS axes: x forward, y left
    ahead_left = SurveyedObstacle("a", np.array([[8.0, 1.0], [9.0, 1.0], [9.0, 2.0], [8.0, 2.0]]))
    recall = RecordedRecall([ahead_left], grid=GridSpec())
    left_ahead = np.array([[-2.0, 8.0], [-1.0, 8.0], [-1.0, 9.0], [-2.0, 9.0]])  # vehicle X right, Y forward
    record = recall.add([left_ahead], None)
    assert record["obstacles"][0]["recalled"] and record["false_alarms"] == 0
    # a detection over nothing surveyed is a false alarm; the summary counts the frames
    elsewhere = np.array([[3.0, 5.0], [4.0, 5.0], [4.0, 6.0], [3.0, 6.0]])
    second = recall.add([elsewhere], None)
    assert not second["obstacles"][0]["recalled"] and second["false_alarms"] == 1
    summary = recall.summary()
    assert (summary["frames"], summary["false_alarms"], summary["false_alarms_per_frame"]) == (2, 1, 0.5)
    assert summary["per_obstacle"] == {"a": {"frames": 2, "recalled": 1}}
