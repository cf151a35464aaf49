"""Scene helpers for the sensor tests."""

import pybullet as p


def static_box(client: int, half_extents, position) -> int:
    """A static box body in a bare PyBullet client; returns its body id."""
    shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half_extents, physicsClientId=client)
    return p.createMultiBody(0, shape, basePosition=position, physicsClientId=client)
