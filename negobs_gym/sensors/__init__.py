"""LiDAR sensor models, rigs, noise and scan synthesis (models/rigs import without pybullet)."""

from negobs_gym.sensors.models import LidarModel, hdl32e, hdl64e_s2, hdl64e_s2_nominal, ibeo_lux
from negobs_gym.sensors.noise import NoiseConfig, apply_noise
from negobs_gym.sensors.rigs import Rig, SensorMount, paper_n_rig, paper_n_rig_reduced, paper_t_rig

__all__ = [
    "LidarModel",
    "NoiseConfig",
    "Rig",
    "SensorMount",
    "apply_noise",
    "hdl32e",
    "hdl64e_s2",
    "hdl64e_s2_nominal",
    "ibeo_lux",
    "paper_n_rig",
    "paper_n_rig_reduced",
    "paper_t_rig",
]
