"""manifold3d solids from and to arrays: the one place the project crosses that boundary.

Solids are built straight from the arrays (never through `trimesh.Trimesh(process=True)`,
which merges vertices and can break watertightness). Frames and units are the caller's.
"""

from __future__ import annotations

import manifold3d as m3
import numpy as np


def to_solid(vertices: np.ndarray, faces: np.ndarray, *, double: bool = True) -> m3.Manifold:
    """manifold3d solid from (V, 3) positions and (F, 3) vertex indices, as given.

    double: keep positions in float64 (manifold3d's `Mesh64`); False rounds them to float32
    (`Mesh`), which certification and the topology check use. Check `.status()` for
    whether manifold3d accepted the mesh.
    """
    # manifold3d takes writeable arrays only: a read-only one (`load_mesh`'s) is copied
    need = ["C_CONTIGUOUS", "WRITEABLE"]
    if double:
        mesh = m3.Mesh64(vert_properties=np.require(vertices, np.float64, need),
                         tri_verts=np.require(faces, np.uint64, need))
    else:
        mesh = m3.Mesh(vert_properties=np.require(vertices, np.float32, need),
                       tri_verts=np.require(faces, np.uint32, need))
    return m3.Manifold(mesh)


def solid_arrays(solid: m3.Manifold) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) float64 positions and (F, 3) int64 faces of a solid, in double precision.

    Double precision: rounding manifold3d's positions to float32 can merge the two vertices
    of a short edge and leave zero-area faces.
    """
    mesh = solid.to_mesh64()
    return (np.asarray(mesh.vert_properties, np.float64)[:, :3],
            np.asarray(mesh.tri_verts, np.int64))


def outside_of(vertices: np.ndarray, faces: np.ndarray, *, double: bool = True,
               margin: float = 1.0) -> m3.Manifold:
    """The region just outside a closed container mesh ((V, 3) positions, (F, 3) faces): a
    box around it, padded by a tenth of its largest extent plus `margin` (one unit, in
    the frame the vertices were scaled from), minus the container. Intersecting a solid
    with it gives the volume outside the container; its `min_gap` to a solid is the wall
    gap. double as in `to_solid`."""
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    pad = 0.1 * float((hi - lo).max()) + margin
    box = m3.Manifold.cube((hi - lo + 2 * pad).tolist(), True).translate(
        ((lo + hi) / 2).tolist())
    return box - to_solid(vertices, faces, double=double)
