"""Read the collision geometry of PyBullet bodies back as triangle meshes (for the fast backend).

Each body's collision shapes come from ``getCollisionShapeData`` (box, sphere, cylinder, capsule,
convex mesh), placed at the pose of their link's inertial frame (``getBasePositionAndOrientation``
for the base, ``getLinkState`` for links) times the shape's local frame — the frames PyBullet
reports them in. Local (body-frame) meshes are cached so moving bodies only need new poses.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pybullet as p

from negobs_gym.errors import SimulationError
from negobs_gym.sensors.raycast.meshes import (
    Mesh,
    box_mesh,
    capsule_mesh,
    convex_hull_mesh,
    cylinder_mesh,
    merge_meshes,
    segments_for,
    sphere_mesh,
    transform_mesh,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LinkMesh:
    """The collision mesh of one link of one body, in the link's inertial frame."""

    body_id: int
    link_index: int  # -1 = base
    mesh: Mesh


def _quat_matrix(q: tuple[float, ...]) -> np.ndarray:
    return np.asarray(p.getMatrixFromQuaternion(q), dtype=np.float64).reshape(3, 3)


def shape_mesh(client_id: int, body_id: int, shape: tuple, chord_error_m: float) -> Mesh:
    """Mesh of one ``getCollisionShapeData`` entry in its link's inertial frame.

    Curved shapes get as many segments as keep them within ``chord_error_m`` of the true surface.

    Raises:
        SimulationError: A shape the backend cannot represent (concave triangle mesh, plane,
            heightfield other than the world's terrain).
    """
    link, geom, dims = shape[1], shape[2], shape[3]
    local_pos, local_orn = np.asarray(shape[5], dtype=np.float64), shape[6]
    if geom == p.GEOM_BOX:
        mesh = box_mesh(0.5 * np.asarray(dims, dtype=np.float64))
    elif geom == p.GEOM_SPHERE:
        r = float(dims[0])
        mesh = sphere_mesh(r, segments_for(r, chord_error_m))
    elif geom == p.GEOM_CYLINDER:  # dims = (height, radius, _)
        r = float(dims[1])
        mesh = cylinder_mesh(r, 0.5 * float(dims[0]), segments_for(r, chord_error_m))
    elif geom == p.GEOM_CAPSULE:  # dims = (cylinder height, radius, _)
        r = float(dims[1])
        mesh = capsule_mesh(r, 0.5 * float(dims[0]), segments_for(r, chord_error_m))
    elif geom == p.GEOM_MESH:
        n, verts = p.getMeshData(body_id, link, physicsClientId=client_id)
        if n < 4:
            raise SimulationError(
                f"body {body_id} link {link}: its mesh shape cannot be read back from PyBullet (a concave "
                "triangle mesh?); use the 'pybullet' ray-cast backend for this world"
            )
        # getMeshData applies meshScale AND the collision frame: the hull is already in the link frame
        return convex_hull_mesh(np.asarray(verts, dtype=np.float64))
    else:
        raise SimulationError(
            f"body {body_id} link {link}: collision shape type {geom} is not supported by the fast "
            "ray-cast backend; use the 'pybullet' backend"
        )
    return transform_mesh(mesh, _quat_matrix(local_orn), local_pos)


def body_link_meshes(client_id: int, body_id: int, chord_error_m: float) -> list[LinkMesh]:
    """Local meshes of every collision shape of ``body_id`` (base and links)."""
    out: list[LinkMesh] = []
    n_links = p.getNumJoints(body_id, physicsClientId=client_id)
    for link in range(-1, n_links):
        parts = [
            shape_mesh(client_id, body_id, s, chord_error_m)
            for s in p.getCollisionShapeData(body_id, link, physicsClientId=client_id)
        ]
        if parts:
            out.append(LinkMesh(body_id, link, merge_meshes(parts)))
    return out


def link_poses(client_id: int, link_meshes: list[LinkMesh]) -> np.ndarray:
    """(K, 7) current world pose (position, quaternion xyzw) of each link's inertial frame."""
    poses = np.empty((len(link_meshes), 7))
    for k, lm in enumerate(link_meshes):
        if lm.link_index < 0:
            pos, orn = p.getBasePositionAndOrientation(lm.body_id, physicsClientId=client_id)
        else:
            st = p.getLinkState(
                lm.body_id, lm.link_index, computeForwardKinematics=True, physicsClientId=client_id
            )
            pos, orn = st[0], st[1]
        poses[k, :3] = pos
        poses[k, 3:] = orn
    return poses


def world_mesh(link_meshes: list[LinkMesh], poses: np.ndarray, local_origin_m: np.ndarray) -> Mesh:
    """All link meshes placed at ``poses`` (from :func:`link_poses`), relative to ``local_origin_m``."""
    placed = [
        transform_mesh(lm.mesh, _quat_matrix(tuple(pose[3:])), pose[:3] - local_origin_m)
        for lm, pose in zip(link_meshes, poses, strict=True)
    ]
    return merge_meshes(placed)
