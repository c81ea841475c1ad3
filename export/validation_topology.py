"""The mesh structure validation reads: identical positions merged, bodies, fans around
vertices, winding patches, duplicate faces and holes, from the one edge topology of
:mod:`jampacked.core.mesh_topology` (numba kernels in :mod:`jampacked.export.meshcheck`).

Faces are (F, 3) int64 indices into merged positions; "proper" faces have three distinct
vertices.
"""

from __future__ import annotations

import numpy as np

from jampacked.core.mesh_topology import EdgeTopology, face_components, open_edge_loops

from . import meshcheck

__all__ = ["duplicate_faces", "face_bodies", "flipped_faces", "holes_per_body",
           "merge_identical", "vertex_fans"]


def merge_identical(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices at exactly identical positions (0.0 and -0.0 are the same).

    Args:
        vertices: (V, 3) float64.

    Returns:
        ``(first, remap)``: (U,) index of the first vertex at each distinct position, in
        order of first occurrence, and (V,) the distinct position of each vertex.
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64) + 0.0  # turns -0.0 into 0.0
    if len(v) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # a hash table on the coordinates' bits: one pass, groups numbered as they appear
    return meshcheck.merge_bits(v.view(np.uint64).reshape(-1, 3))


def face_bodies(faces: np.ndarray, proper: np.ndarray, topo: EdgeTopology
                ) -> tuple[int, np.ndarray]:
    """Body of each face, numbered in the order of each body's first proper face.

    Proper faces sharing an edge are in one body. A face with a repeated vertex (a line or a
    point) joins the body of a proper face at one of its vertices, or is a body of its own.
    """
    return face_components(faces, topo, proper)


def vertex_fans(faces: np.ndarray, proper: np.ndarray, topo: EdgeTopology
                ) -> tuple[np.ndarray, np.ndarray]:
    """Fans of faces around each vertex, joined across edges used by exactly two faces.

    Returns (vertex of each fan, a proper face of each fan).
    """
    return meshcheck.fans(faces, proper, topo.first_corner, topo.second_corner,
                          topo.inconsistent)


def flipped_faces(n_faces: int, topo: EdgeTopology) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose winding disagrees with the majority of their patch, and faces on
    non-orientable patches. A patch: faces joined across edges used by exactly two faces."""
    return meshcheck.flipped_faces(n_faces, topo.first_corner, topo.second_corner,
                                   topo.inconsistent)


def duplicate_faces(faces: np.ndarray, proper: np.ndarray, topo: EdgeTopology) -> np.ndarray:
    """Indices of proper faces on the same three vertices as an earlier face (any winding)."""
    return meshcheck.duplicate_faces(faces, proper, topo.corner_edge, topo.counts,
                                     topo.first_corner, topo.second_corner)


def holes_per_body(topo: EdgeTopology, face_body: np.ndarray, n_bodies: int) -> np.ndarray:
    """Boundary loops (connected groups of open edges) per body."""
    open_edges, loop = open_edge_loops(topo)
    if len(open_edges) == 0:
        return np.zeros(n_bodies, np.int64)
    # the body of an open edge: the body of a face using it
    body = face_body[topo.face_of_edge[open_edges]]
    n = np.int64(loop.max() + 1)
    keys = np.unique(body * n + loop)
    return np.bincount(keys // n, minlength=n_bodies)
