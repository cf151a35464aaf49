import numpy as np
import pytest

from negobs_gym.errors import ConfigError
from negobs_gym.sensors.raycast.pybullet_backend import MAX_BATCH, PyBulletCaster
from tests.sensors.helpers import static_box


def test_rays_through_excluded_bodies_hit_what_is_behind(client):
    wall = static_box(client, [5, 0.5, 5], [0, 10.5, 0])
    a = static_box(client, [1, 1, 1], [0, 3, 0])
    b = static_box(client, [1, 1, 1], [0, 6, 0])
    o = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.5], [3.0, 0.0, 0.0]])
    d = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(PyBulletCaster(client).cast(o, d, 50.0), [2.0, 2.0, 10.0], atol=1e-4)
    np.testing.assert_allclose(
        PyBulletCaster(client, exclude_body_ids=[a]).cast(o, d, 50.0), [5.0, 5.0, 10.0], atol=1e-4
    )
    both = PyBulletCaster(client, exclude_body_ids=[a, b]).cast(o, d, 50.0)
    np.testing.assert_allclose(both, [10.0, 10.0, 10.0], atol=1e-4)
    everything = PyBulletCaster(client, exclude_body_ids=[a, b, wall]).cast(o, d, 50.0)
    assert np.isnan(everything).all()


def test_more_rays_than_one_batch(client):
    static_box(client, [100, 100, 1], [0, 0, -1])
    n = 2 * MAX_BATCH + 5
    o = np.column_stack([np.linspace(-50, 50, n), np.zeros(n), np.full(n, 3.0)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    r = PyBulletCaster(client).cast(o, d, 10.0)
    np.testing.assert_allclose(r, 3.0, atol=1e-4)


def test_bad_config():
    with pytest.raises(ConfigError, match="max_hits_per_ray"):
        PyBulletCaster(0, max_hits_per_ray=1)
