"""negobs_gym: off-road negative-obstacle simulation, detection and safe-navigation environments.

Subpackages, each owning one thing:

- :mod:`negobs_gym.core` — poses, structured scans, vehicle-centred grids (numpy only)
- :mod:`negobs_gym.sim` — procedural terrain, PyBullet world and vehicle
- :mod:`negobs_gym.sensors` — LiDAR models, rigs and ray casting
- :mod:`negobs_gym.detector` — paper N and paper T detectors (no simulator import)
- :mod:`negobs_gym.envs` — Gymnasium environments
- :mod:`negobs_gym.safety` — the Eq. 18 braking-distance safety filter
- :mod:`negobs_gym.drivers` — scripted drivers
- :mod:`negobs_gym.eval` — detection and braking evaluation

Importing the package registers the environments with gymnasium (lazily, see
:mod:`negobs_gym.registration`).
"""

from negobs_gym.errors import ConfigError, NegobsError
from negobs_gym.registration import register_now_or_on_gymnasium_import

__version__ = "0.1.0"
__all__ = ["ConfigError", "NegobsError", "__version__"]

register_now_or_on_gymnasium_import()
