import numpy as np

from negobs_gym.envs.config import EnvConfig
from negobs_gym.envs.scenarios import BrakingEnv


def test_observed_layer_is_the_cells_of_the_frames_returns() -> None:
    env = BrakingEnv(EnvConfig())
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
