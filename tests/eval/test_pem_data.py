"""The PEM drives' judge: which obstacles a drawn blob counts for."""

import numpy as np
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
