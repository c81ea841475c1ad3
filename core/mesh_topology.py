"""Edge topology of triangle meshes: one computation of which faces share which edge,
used by loading (:mod:`jampacked.core.mesh_repair`) and by validation
(:mod:`jampacked.export.validate`).

Faces are (F, 3) int64 vertex indices. Corner c = 3 * face + slot starts the half-edge from
that vertex to the next one of its face. "Proper" faces have three distinct vertices; use
counts and pairing come from them only. The kernels are numba (validation runs them on
meshes of millions of faces); each gives exactly what the numpy formulation it replaced
gave (tests/test_validate_kernels.py holds those references).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

__all__ = [
    "EdgeTopology",
    "edge_topology",
    "face_components",
    "open_edge_loops",
    "uf_find",
    "uf_flatten",
    "uf_union",
    "union_roots",
]


@dataclass(frozen=True)
class EdgeTopology:
    """Undirected edges of a mesh (see :func:`edge_structure`); self-loops (a->a) have no
    edge."""

    corner_edge: np.ndarray  # (3F,) edge of each corner, -1 for a self-loop
    edge_vertices: np.ndarray  # (E, 2) smaller, larger vertex
    counts: np.ndarray  # (E,) proper faces using each edge
    first_corner: np.ndarray  # (E,) first proper corner of edges used twice, else -1
    second_corner: np.ndarray  # (E,) second proper corner of edges used twice, else -1
    inconsistent: np.ndarray  # (E,) bool: used by two faces running the same way
    face_of_edge: np.ndarray  # (E,) the face of each edge's last corner


def edge_topology(faces: np.ndarray, n_vertices: int,
                  proper: np.ndarray | None = None) -> EdgeTopology:
    """Undirected edges, their use counts, and the two corners of each edge used twice.

    Args:
        faces: (F, 3) int64 vertex indices in [0, n_vertices).
        n_vertices: number of vertices.
        proper: (F,) bool, the faces with three distinct vertices (computed when None).
    """
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    if proper is None:
        proper = ((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
                  & (faces[:, 2] != faces[:, 0]))
    return EdgeTopology(*edge_structure(faces, proper, n_vertices))


def face_components(faces: np.ndarray, topo: EdgeTopology,
                    proper: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """Edge-connected components of the faces: ``(count, (F,) label of each face)``, labels
    in the order of each component's first face.

    Proper faces sharing an edge are in one component. A face with a repeated vertex (a line
    or a point) joins the component of a proper face at one of its vertices, or is a
    component of its own.
    """
    if len(faces) == 0:
        return 0, np.zeros(0, np.int64)
    if proper is None:
        proper = np.ones(len(faces), np.bool_)
    n, labels = face_bodies(len(faces), proper, np.ascontiguousarray(faces, dtype=np.int64),
                            topo.corner_edge, len(topo.counts))
    return int(n), labels


def open_edge_loops(topo: EdgeTopology) -> tuple[np.ndarray, np.ndarray]:
    """The open edges (used by one proper face) and the boundary loop of each: connected
    groups of open edges, each numbered by its smallest vertex slot (not consecutive)."""
    open_edges = np.flatnonzero(topo.counts == 1)
    if len(open_edges) == 0:
        return open_edges, np.zeros(0, np.int64)
    used, local = np.unique(topo.edge_vertices[open_edges], return_inverse=True)
    local = local.reshape(-1, 2)
    return open_edges, union_roots(len(used), local[:, 0], local[:, 1])[local[:, 0]]


@njit(cache=True)
def edge_structure(faces: np.ndarray, proper: np.ndarray, n_vertices: int
                   ) -> tuple[np.ndarray, ...]:
    """The face corners' edges grouped into undirected edges.

    Corner c = 3 * face + slot starts the half-edge from that vertex to the next one of its
    face; corners whose half-edge is a self-loop (a->a) have no edge. Edges are numbered in
    order of (smaller vertex, larger vertex), as a sort of their keys would; within an edge
    its corners are in order. Use counts, pairing and "inconsistent" (two faces running the
    same way) come from proper faces (three distinct vertices) only.

    Returns:
        corner_edge: (3F,) edge of each corner, -1 for a self-loop;
        edge_vertices: (E, 2) smaller, larger vertex;
        counts: (E,) proper faces using each edge;
        first_corner, second_corner: (E,) the two proper corners of edges used by exactly
            two proper faces (in order), else -1;
        inconsistent: (E,) bool, used twice by faces running the same way;
        face_of_edge: (E,) the face of each edge's last corner.
    """
    n_faces = faces.shape[0]
    n_corners = 3 * n_faces
    # corners bucketed by their edge's smaller vertex (a stable counting sort)
    start = np.zeros(n_vertices + 1, np.int64)
    for f in range(n_faces):
        for s in range(3):
            a = faces[f, s]
            b = faces[f, 0 if s == 2 else s + 1]
            if a != b:
                start[min(a, b) + 1] += 1
    for v in range(n_vertices):
        start[v + 1] += start[v]
    n_half = start[n_vertices]
    order = np.empty(n_half, np.int64)  # corners
    other = np.empty(n_half, np.int64)  # their edge's larger vertex
    fill = start[:-1].copy()
    for f in range(n_faces):
        for s in range(3):
            a = faces[f, s]
            b = faces[f, 0 if s == 2 else s + 1]
            if a != b:
                v = min(a, b)
                k = fill[v]
                order[k] = 3 * f + s
                other[k] = max(a, b)
                fill[v] = k + 1
    # each bucket sorted (stably) by the larger vertex; edges numbered as they come
    corner_edge = np.full(n_corners, -1, np.int64)
    edge_vertices = np.empty((n_half, 2), np.int64)
    counts = np.empty(n_half, np.int64)
    first_corner = np.empty(n_half, np.int64)
    second_corner = np.empty(n_half, np.int64)
    face_of_edge = np.empty(n_half, np.int64)
    e = -1
    for v in range(n_vertices):
        s0, s1 = start[v], start[v + 1]
        if s1 - s0 > 32:
            sub = np.argsort(other[s0:s1], kind="mergesort")
            bucket = order[s0:s1].copy()
            keys = other[s0:s1].copy()
            for t in range(s1 - s0):
                order[s0 + t] = bucket[sub[t]]
                other[s0 + t] = keys[sub[t]]
        else:
            for t in range(s0 + 1, s1):  # insertion sort, stable
                cur = order[t]
                key = other[t]
                u = t - 1
                while u >= s0 and other[u] > key:
                    order[u + 1] = order[u]
                    other[u + 1] = other[u]
                    u -= 1
                order[u + 1] = cur
                other[u + 1] = key
        prev = -1
        for t in range(s0, s1):
            c = order[t]
            if other[t] != prev:
                prev = other[t]
                e += 1
                edge_vertices[e, 0] = v
                edge_vertices[e, 1] = prev
                counts[e] = 0
                first_corner[e] = -1
                second_corner[e] = -1
            corner_edge[c] = e
            face_of_edge[e] = c // 3  # corners come in order: the last one stays
            if proper[c // 3]:
                k = counts[e]
                if k == 0:
                    first_corner[e] = c
                elif k == 1:
                    second_corner[e] = c
                counts[e] = k + 1
    n_edges = e + 1
    inconsistent = np.zeros(n_edges, np.bool_)
    for e in range(n_edges):
        if counts[e] == 2:
            c1, c2 = first_corner[e], second_corner[e]
            inconsistent[e] = faces[c1 // 3, c1 % 3] == faces[c2 // 3, c2 % 3]
        else:
            first_corner[e] = -1
            second_corner[e] = -1
    return (corner_edge, edge_vertices[:n_edges], counts[:n_edges], first_corner[:n_edges],
            second_corner[:n_edges], inconsistent, face_of_edge[:n_edges])


@njit(cache=True, inline="always")
def uf_find(parent, x):
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


@njit(cache=True, inline="always")
def uf_union(parent, a, b):
    """Join the sets of a and b under the smaller root (so each root ends as the smallest
    node of its set, whatever the order of the unions)."""
    x = uf_find(parent, a)
    y = uf_find(parent, b)
    if x < y:
        parent[y] = x
    elif y < x:
        parent[x] = y


@njit(cache=True, inline="always")
def uf_flatten(parent):
    for i in range(parent.shape[0]):  # parent[i] <= i: parents are final when i is reached
        parent[i] = parent[parent[i]]


@njit(cache=True)
def union_roots(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Union-find over n nodes joined by edges a-b: each node's root, the smallest node of
    its connected component."""
    parent = np.arange(n)
    for k in range(a.shape[0]):
        uf_union(parent, a[k], b[k])
    uf_flatten(parent)
    return parent


@njit(cache=True)
def face_bodies(n_faces: int, proper: np.ndarray, faces: np.ndarray, corner_edge: np.ndarray,
                n_edges: int) -> tuple[int, np.ndarray]:
    """Body of each face, numbered in the order of each body's first face (see
    :func:`face_components`)."""
    parent = np.arange(n_faces + n_edges)
    for c in range(corner_edge.shape[0]):
        f = c // 3
        if proper[f] and corner_edge[c] >= 0:
            uf_union(parent, f, corner_edge[c] + n_faces)
    uf_flatten(parent)
    root = parent[:n_faces].copy()
    n_vertices = 0
    all_proper = True
    for f in range(n_faces):
        if not proper[f]:
            all_proper = False
        for k in range(3):
            n_vertices = max(n_vertices, faces[f, k] + 1)
    if not all_proper:
        # a line or point face joins the body of a proper face at one of its vertices
        vertex_root = np.full(n_vertices, -1, np.int64)
        for f in range(n_faces):
            if proper[f]:
                for k in range(3):
                    vertex_root[faces[f, k]] = root[f]
        for f in range(n_faces):
            if not proper[f]:
                owner = max(vertex_root[faces[f, 0]], vertex_root[faces[f, 1]],
                            vertex_root[faces[f, 2]])
                if owner >= 0:
                    root[f] = owner
    rank = np.full(n_faces, -1, np.int64)
    n_bodies = 0
    is_root = np.zeros(n_faces, np.bool_)
    for f in range(n_faces):
        is_root[root[f]] = True
    for f in range(n_faces):
        if is_root[f]:
            rank[f] = n_bodies
            n_bodies += 1
    body = np.empty(n_faces, np.int64)
    for f in range(n_faces):
        body[f] = rank[root[f]]
    return n_bodies, body
