"""The PEM drives: the judge (which obstacles a drawn blob counts for) and the courses' controller."""

import numpy as np
import pytest
from scipy import ndimage

from negobs_gym.eval.pem_data import blob_counts


def _labels(layer: np.ndarray) -> tuple[np.ndarray, int]:
    return ndimage.label(layer, structure=np.ones((3, 3), dtype=bool))


def _mound_and_rock() -> tuple[np.ndarray, np.ndarray]:
    mound = np.zeros((12, 12), dtype=bool)
    mound[1:8, 1:8] = True
    rock = np.zeros_like(mound)
    rock[3:5, 3:5] = True
    return mound, rock


def test_a_rocks_face_on_a_mound_counts_for_the_rock_alone() -> None:
    mound, rock = _mound_and_rock()
    layer = np.zeros_like(mound)
    layer[3:5, 3:5] = True  # the rock's face, inside both footprints
    layer[10, 11] = True  # touches nothing even grown by 1
    labels, count = _labels(layer)
    for truths, rock_index in (([mound, rock], 1), ([rock, mound], 0)):
        counts = blob_counts(labels, count, truths, match_cells=1)
        assert counts.shape == (2, count + 1) and not counts[:, 0].any()
        face, stray = labels[3, 3], labels[10, 11]
        assert counts[rock_index, face] and not counts[1 - rock_index, face]
        assert not counts[:, stray].any()


def test_a_blob_over_two_obstacles_counts_for_both_and_one_beside_by_the_grown_mask() -> None:
    mound, rock = _mound_and_rock()
    layer = np.zeros_like(mound)
    layer[4, 2:6] = True  # on the rock and on the mound beside it
    layer[9, 5] = True  # beside the mound: inside it grown by 2, not by 1
    labels, count = _labels(layer)
    counts = blob_counts(labels, count, [mound, rock], match_cells=2)
    assert counts[:, labels[4, 2]].all()
    assert counts[0, labels[9, 5]] and not counts[1, labels[9, 5]]
    assert not blob_counts(labels, count, [mound, rock], match_cells=1)[:, labels[9, 5]].any()
    assert blob_counts(labels, count, [], match_cells=0).shape == (0, count + 1)


def test_the_courses_controller_steers_to_the_line_shifted_by_the_path_offset() -> None:
    from negobs_gym.core.pose import Pose
    from negobs_gym.eval.pem_data import path_steering

    line = np.array([[0.0, 0.0], [0.0, 100.0]])  # a course along +y
    assert path_steering(Pose(x=0.0, y=10.0), line) == 0.0
    assert path_steering(Pose(x=1.2, y=10.0), line, 1.2) == 0.0  # on its shifted line
    assert path_steering(Pose(x=1.2, y=10.0), line) == pytest.approx(0.6)  # back towards x = 0
    assert path_steering(Pose(x=0.0, y=10.0), line, 1.2) == pytest.approx(-0.6)
    assert path_steering(Pose(x=1.2, y=10.0, yaw=0.1), line, 1.2) == pytest.approx(-0.2)  # and to its heading
    assert path_steering(Pose(x=9.0, y=10.0), line) == 1.0  # full lock at most


@pytest.mark.parametrize("offset", [float("nan"), float("inf")])
def test_a_path_offset_that_is_not_finite_is_refused(offset: float) -> None:
    from negobs_gym.errors import ConfigError
    from negobs_gym.eval.pem_data import PemCampaignConfig

    with pytest.raises(ConfigError, match="path_offset_m"):
        PemCampaignConfig(path_offset_m=offset)
    assert PemCampaignConfig(path_offset_m=-1.2).path_offset_m == -1.2
