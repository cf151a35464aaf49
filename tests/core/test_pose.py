import math

import numpy as np
import pytest

from negobs_gym.core import Pose, rotation_from_rpy
from negobs_gym.core.pose import pose_from_matrix
from negobs_gym.errors import ScanError


def test_yaw_zero_faces_world_plus_y_and_positive_yaw_turns_left():
    assert np.allclose(Pose().heading, [0.0, 1.0])
    left = Pose(yaw=math.pi / 2)
    assert np.allclose(left.heading, [-1.0, 0.0])
    # the vehicle's right (+X) points to world +Y after a left quarter turn
    assert np.allclose(left.to_world([1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])


def test_positive_pitch_lifts_the_nose_and_positive_roll_lowers_the_right_side():
    assert Pose(pitch=0.1).to_world([0.0, 1.0, 0.0])[2] > 0
    assert Pose(roll=0.1).to_world([1.0, 0.0, 0.0])[2] < 0


@pytest.mark.parametrize("rpy", [(0.1, -0.2, 2.5), (-0.3, 0.05, -1.0), (0.0, 0.0, 3.1)])
def test_rotation_is_orthonormal_and_world_vehicle_round_trip(rpy):
    r = rotation_from_rpy(*rpy)
    assert np.allclose(r @ r.T, np.eye(3))
    assert np.isclose(np.linalg.det(r), 1.0)
    pose = Pose(3.0, -2.0, 0.5, *rpy)
    pts = np.random.default_rng(0).normal(size=(7, 3))
    assert np.allclose(pose.to_vehicle(pose.to_world(pts)), pts)


def test_pose_rejects_nan_and_wrong_length():
    with pytest.raises(ScanError, match="non-finite"):
        Pose(x=float("nan"))
    with pytest.raises(ScanError, match="6 values"):
        Pose.from_array([1.0, 2.0])
    assert Pose.from_array(Pose(1, 2, 3, 0.1, 0.2, 0.3).as_array()) == Pose(1, 2, 3, 0.1, 0.2, 0.3)


def test_pose_from_matrix_inverts_core_rotation():
    rng = np.random.default_rng(0)
    for roll, pitch, yaw in rng.uniform(-1.2, 1.2, size=(20, 3)):
        ref = Pose(1.0, 2.0, 3.0, roll, pitch, yaw)
        got = pose_from_matrix(ref.translation, ref.rotation)
        np.testing.assert_allclose(got.as_array(), ref.as_array(), atol=1e-9)
