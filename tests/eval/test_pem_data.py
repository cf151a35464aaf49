"""The PEM drives' judge: which obstacle a drawn blob counts for."""

import numpy as np
from scipy import ndimage

from negobs_gym.eval.pem_data import blob_owners


def _labels(layer: np.ndarray) -> tuple[np.ndarray, int]:
    return ndimage.label(layer, structure=np.ones((3, 3), dtype=bool))


def test_a_blob_counts_for_one_obstacle_the_rock_it_is_drawn_on_not_the_mound_under_it() -> None:
    mound = np.zeros((12, 12), dtype=bool)
    mound[1:8, 1:8] = True
    rock = np.zeros_like(mound)
    rock[3:5, 3:5] = True
    layer = np.zeros_like(mound)
    layer[3:5, 3:5] = True  # the rock's face, inside both footprints
    layer[9, 10] = True  # touches nothing even grown by 1
    labels, count = _labels(layer)
    for truths, rock_index in (([mound, rock], 1), ([rock, mound], 0)):
        owner = blob_owners(labels, count, truths, match_cells=1)
        assert owner[0] == -1
        assert owner[labels[3, 3]] == rock_index
        assert owner[labels[9, 10]] == -1


def test_a_blob_goes_to_the_obstacle_it_overlaps_most() -> None:
    left = np.zeros((6, 12), dtype=bool)
    left[1:5, 0:4] = True
    right = np.zeros_like(left)
    right[1:5, 5:9] = True
    layer = np.zeros_like(left)
    layer[2, 2:8] = True  # two cells on the left one, three on the right one
    labels, count = _labels(layer)
    assert blob_owners(labels, count, [left, right], match_cells=0)[1] == 1
    assert blob_owners(labels, count, [], match_cells=0).tolist() == [-1, -1]
