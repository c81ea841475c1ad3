"""Geometry of triangle meshes given as arrays: face areas, signed volumes, the volume
centroid, and points sampled over the surface.

Pure functions over ``vertices`` (V, 3) float64 and ``faces`` (F, 3) int64; results are in
the vertices' units and frame.
"""

from __future__ import annotations

import numpy as np

__all__ = ["face_areas2", "mesh_volume_centroid", "sample_surface", "signed_six_volumes"]


def face_areas2(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) twice the area of each face (the norm of its edge cross product), units²."""
    tri = vertices[faces]
    return np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def signed_six_volumes(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(F,) six times the signed volume of the tetrahedron of each face with the bounding-box
    centre (taken about the centre for precision), units³; their sum over a closed, outward
    wound mesh is six times its volume."""
    origin = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    tri = vertices[faces] - origin
    return np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))


def mesh_volume_centroid(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, np.ndarray]:
    """Exact signed volume and volume centroid of a closed triangle mesh (divergence theorem).

    Args:
        vertices: (V, 3) positions, any units.
        faces: (F, 3) vertex indices; outward (counter-clockwise) winding gives volume > 0.

    Returns:
        ``(volume, centroid)``: volume in units cubed (negative for an inside-out mesh) and the
        (3,) float64 centroid in the vertices' frame. The sum of signed tetrahedra is taken
        about the bounding-box centre for precision. If the volume is zero the centroid is
        undefined and the bounding-box centre is returned.
    """
    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(faces) == 0 or len(vertices) == 0:
        return 0.0, np.zeros(3)
    origin = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    tri = vertices[faces] - origin
    six_vol = signed_six_volumes(vertices, faces)
    volume = float(six_vol.sum() / 6.0)
    if volume == 0.0:
        return 0.0, origin
    corners = tri[:, 0] + tri[:, 1] + tri[:, 2]
    centroid = (six_vol[:, None] * corners).sum(axis=0) / (24.0 * volume) + origin
    return volume, centroid


def sample_surface(vertices: np.ndarray, faces: np.ndarray, n: int,
                   seed: int = 0) -> np.ndarray:
    """(n, 3) points uniformly distributed by area over a triangle mesh (seeded).

    Faces are drawn with probability proportional to their area, then a point uniformly
    inside each drawn face (the square-root warp). The draw is this project's own rather
    than ``trimesh.sample.sample_surface``: the contact margins are measured on these
    points, and another random stream would change every packing (docs/notes-meshes-io.md).
    """
    tri = vertices[faces]
    area = 0.5 * face_areas2(vertices, faces)
    rng = np.random.default_rng(seed)
    pick = rng.choice(len(faces), size=n, p=area / area.sum())
    r1 = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    t = tri[pick]
    return (t[:, 0] * (1 - r1)[:, None] + t[:, 1] * (r1 * (1 - r2))[:, None]
            + t[:, 2] * (r1 * r2)[:, None])


def inner_room(vertices: np.ndarray, faces: np.ndarray) -> float:
    """A lower bound of a closed mesh's inscribed radius (the depth a container needs to
    hold it in any orientation), in the mesh's units: the distance from its volume centroid
    to its surface where the centroid is inside, else its volume over its area (a lower
    bound for convex shapes: their inner parallel surfaces shrink)."""
    from .distance import distances_to_given_triangles, inside_mask

    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    volume, centroid = mesh_volume_centroid(v, f)
    area = 0.5 * float(face_areas2(v, f).sum())
    room = volume / area if area > 0 else 0.0
    if inside_mask(v, f, centroid, 1.0, (1, 1, 1))[0, 0, 0]:
        near = distances_to_given_triangles(np.repeat(centroid[None], len(f), axis=0),
                                            np.arange(len(f)), v, f)
        room = max(room, float(near.min()))
    return room
