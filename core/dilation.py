"""What a printing clearance costs physically: the volume an object gains when dilated.

With a clearance c every object keeps c from its neighbours, so each object's own room is
the object dilated by c/2 (its Minkowski sum with a ball of radius c/2). Dilated objects
packed as densely as the bare ones would fill the container to the same fraction, so the
best density a clearance allows is the density without it times V / V(c/2): the
clearance's physical cost is 1 - V / V(c/2).

V(r) is the Steiner polynomial of the closed mesh, V + A r + (r^2 / 2) sum_e l_e theta_e
+ (4 pi / 3) r^3 (chi / 2), with the volume V and area A from manifold3d, l_e and theta_e
each edge's length and signed exterior dihedral angle (negative on concave edges) and chi
the Euler characteristic. It is exact for convex meshes; on concave edges the r^2 term is
approximate, which at clearances far below an object's size moves the cost by a small
fraction of itself (measured against manifold3d's Minkowski sum: docs/notes-core.md).
manifold3d's own Minkowski sum of a 16,000-face scan took minutes per type here.
Lengths in the mesh's units.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from .solids import to_solid


def dilated_volume(vertices: np.ndarray, faces: np.ndarray, r: float) -> float:
    """Volume of a closed mesh ((V,3) positions, (F,3) faces) dilated by r >= 0 (its
    Minkowski sum with a ball of radius r), by the Steiner polynomial (module doc)."""
    if r < 0:
        raise ValueError(f"dilation radius must be >= 0, got {r!r}")
    vertices = np.array(vertices, np.float64)  # a writeable copy: manifold3d needs one
    faces = np.array(faces, np.int64)
    solid = to_solid(vertices, faces)
    volume, area = float(solid.volume()), float(solid.surface_area())
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    edges = mesh.face_adjacency_edges
    lengths = np.linalg.norm(mesh.vertices[edges[:, 0]] - mesh.vertices[edges[:, 1]], axis=1)
    angles = np.where(mesh.face_adjacency_convex, 1.0, -1.0) * mesh.face_adjacency_angles
    chi = len(mesh.vertices) - len(edges) + len(mesh.faces)
    return (volume + area * r + 0.5 * r * r * float(np.sum(lengths * angles))
            + (4.0 * np.pi / 3.0) * r ** 3 * chi / 2.0)


def clearance_cost(meshes: Sequence[tuple[np.ndarray, np.ndarray]], shares: Sequence[float],
                   clearance: float) -> dict:
    """The physical cost of a clearance for a mix of types: each type dilated by half the
    clearance (its own room), mixed by count `shares` (normalised here).

    Returns {"per_type": [1 - V_t / V_t(c/2)], "scene": 1 - sum q_t V_t / sum q_t V_t(c/2)}:
    a packing with the clearance can reach at most (1 - scene) times the density of the
    same packing without it.
    """
    q = np.asarray(shares, np.float64)
    if len(q) != len(meshes) or np.any(q < 0) or q.sum() <= 0:
        raise ValueError("shares must be one non-negative weight per mesh, not all zero")
    q = q / q.sum()
    bare = np.array([float(to_solid(np.array(v, np.float64), np.array(f, np.int64)).volume())
                     for v, f in meshes])
    grown = np.array([dilated_volume(v, f, 0.5 * clearance) for v, f in meshes])
    return {"per_type": [float(x) for x in 1.0 - bare / grown],
            "scene": float(1.0 - np.sum(q * bare) / np.sum(q * grown))}
