"""Ray-casting backends behind one interface (see :mod:`.base`)."""

from negobs_gym.sensors.raycast.base import RayCaster

__all__ = ["RayCaster"]
