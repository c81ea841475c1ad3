"""Check a triangle mesh and repair what is safe to repair: the pipeline behind
:func:`jampacked.core.meshes.load_mesh`.

:func:`check_and_repair` runs named stages in order: refuse unreadable arrays; merge
vertices at (nearly) the same position; remove degenerate faces (splitting needles so the
surface stays closed), duplicate faces and zero-area pieces; require a closed 2-manifold
surface; make the winding consistent; drop zero-volume sliver bodies; require one body;
turn an inside-out mesh outward; verify the guarantees with our own edge count and with
manifold3d; and, for containers, refuse a thin wall around a cavity.

Repairs come back as full sentences naming the mesh; defects that cannot be repaired safely
raise :class:`~jampacked.core.errors.MeshError` naming the mesh, the defect with counts, and
a fix. Units and frame are the caller's: nothing is scaled, rotated or moved.
"""

from __future__ import annotations

import manifold3d
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError, cKDTree

from .errors import MeshError, plural
from .mesh_files import obj_malformed_polygons
from .mesh_geometry import face_areas2, mesh_volume_centroid, signed_six_volumes
from .mesh_topology import EdgeTopology, edge_topology, face_components, open_edge_loops
from .solids import to_solid

__all__ = [
    "CRACK_TOLERANCE",
    "MERGE_TOLERANCE",
    "SLIVER_AREA_FRACTION",
    "SLIVER_VOLUME_FRACTION",
    "THIN_WALL_HULL_FILL",
    "THIN_WALL_THICKNESS",
    "UNWELDED_SHARE",
    "ZERO_VOLUME_FRACTION",
    "check_and_repair",
    "manifold_status",
    "unwelded_share",
]

# Vertices closer than this fraction of the bounding-box diagonal are the same vertex.
MERGE_TOLERANCE = 1e-9
# Open-boundary vertices this close (fraction of the diagonal) to another are a crack
# between unwelded faces, for the message's advice; nothing is merged at this distance.
CRACK_TOLERANCE = 1e-5
# ... and a mesh at least this share of whose open-boundary vertices are such cracks is
# unwelded rather than holed
UNWELDED_SHARE = 0.5
#: coordinates beyond this are refused: a volume (a length cubed) overflows past 1e102
MAX_COORDINATE = 1e100
#: a mesh so far from the origin that float64's step there exceeds this fraction of its
#: size is refused: placing it composes its transforms at that distance, where each
#: rounding moves it by a step (the file frame's matrices in the packing file, as users and
#: checkers apply them); at 1e15 a 8-unit cube moved 1.6% and overlapped its neighbour
FAR_PRECISION = 1e-7
# A face whose height is below MERGE_TOLERANCE * diagonal is degenerate (zero area).
# A connected piece whose area is below this fraction of the total area is a sliver.
SLIVER_AREA_FRACTION = 1e-6
# A closed body whose |volume| is below this fraction of the largest body's is a sliver.
SLIVER_VOLUME_FRACTION = 1e-6
# A mesh whose |volume| is below this fraction of diagonal**3 has zero volume.
ZERO_VOLUME_FRACTION = 1e-12
# Thin-wall container test: mean wall thickness 2V/A relative to the convex hull's size
# (cube root of its volume), and the share of the convex hull the solid fills. Chosen
# between the test containers and a printed vase's wall (docs/notes-meshes-io.md).
THIN_WALL_THICKNESS = 0.08
THIN_WALL_HULL_FILL = 0.5

_FIX_REEXPORT = "re-export it from your modelling tool as a closed solid"


def _cap(text: str) -> str:
    return text[:1].upper() + text[1:]


def manifold_status(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Error:
    """manifold3d's status of the mesh in single precision (``Error.NoError``: accepted)."""
    return to_solid(vertices, faces, double=False).status()


# --------------------------------------------------------------------------------------------
# repair steps


def _merge_vertices(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge identical positions, then positions within MERGE_TOLERANCE * diagonal.

    Keeps the order of first occurrence. Faces are re-indexed; nothing is removed here.
    """
    if len(vertices) == 0:
        return vertices, faces
    _, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    vertices = vertices[first[order]]
    faces = rank[inverse.reshape(-1)][faces]
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    tol = MERGE_TOLERANCE * diagonal
    if tol > 0 and len(vertices) > 1:
        pairs = cKDTree(vertices).query_pairs(tol, output_type="ndarray")
        if len(pairs):
            n = len(vertices)
            graph = coo_matrix(
                (np.ones(len(pairs), np.int8), (pairs[:, 0], pairs[:, 1])), shape=(n, n)
            )
            _, labels = connected_components(graph, directed=False)
            _, first, labels = np.unique(labels, return_index=True, return_inverse=True)
            order = np.argsort(first)
            rank = np.empty_like(order)
            rank[order] = np.arange(len(order))
            vertices = vertices[first[order]]
            faces = rank[labels.reshape(-1)][faces]
    return vertices, faces


def _split_needles(
    vertices: np.ndarray, faces: np.ndarray, needle: np.ndarray
) -> tuple[np.ndarray, int]:
    """Remove zero-area faces with three distinct vertices, keeping the surface closed.

    A needle (a, b, c) has c on the segment ab. The face across edge ab is split at c,
    which closes the gap the needle leaves (a T-junction repair). Needles whose neighbour
    cannot be found (open or non-manifold there) are left in place.
    """
    faces = faces.copy()
    alive = np.ones(len(faces), bool)
    extra: list[np.ndarray] = []
    removed = 0
    for index in np.flatnonzero(needle):
        if not alive[index]:
            continue
        face = faces[index]
        tri = vertices[face]
        lengths = np.linalg.norm(tri[[1, 2, 0]] - tri, axis=1)  # edge k: face[k] -> face[k+1]
        k = int(np.argmax(lengths))
        a, b, c = face[k], face[(k + 1) % 3], face[(k + 2) % 3]
        # the neighbour holds the directed edge b -> a
        cand = np.flatnonzero(
            alive
            & (((faces[:, 0] == b) & (faces[:, 1] == a))
               | ((faces[:, 1] == b) & (faces[:, 2] == a))
               | ((faces[:, 2] == b) & (faces[:, 0] == a)))
        )
        cand = cand[cand != index]
        if len(cand) != 1 or needle[cand[0]]:
            continue
        other = faces[cand[0]]
        j = int(np.flatnonzero(other == b)[0])
        d = other[(j + 2) % 3]
        if d == c:
            continue
        alive[index] = False
        alive[cand[0]] = False
        extra.append(np.array([[b, c, d], [c, a, d]], dtype=np.int64))
        removed += 1
    if extra:
        faces = np.concatenate([faces[alive], *extra])
    else:
        faces = faces[alive]
    return faces, removed


def _remove_duplicates(faces: np.ndarray, n_vertices: int) -> tuple[np.ndarray, int, int]:
    """Drop repeated faces. Returns (faces, same-orientation copies, opposite pairs removed).

    Faces on the same three vertices are grouped; copies with the same orientation collapse
    to one, and a face and its reverse cancel (together they are a zero-volume sliver).
    """
    srt = np.sort(faces, axis=1)
    if n_vertices < 2_000_000:  # n**3 fits in int64
        n = np.int64(max(n_vertices, 1))
        keys = (srt[:, 0] * n + srt[:, 1]) * n + srt[:, 2]
        _, inverse, counts = np.unique(keys, return_inverse=True, return_counts=True)
    else:
        _, inverse, counts = np.unique(srt, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.reshape(-1)
    if np.all(counts == 1):
        return faces, 0, 0
    # orientation sign: rotate the smallest index first, then compare the other two
    rot = np.argmin(faces, axis=1)
    second = faces[np.arange(len(faces)), (rot + 1) % 3]
    third = faces[np.arange(len(faces)), (rot + 2) % 3]
    sign = np.where(second < third, 1, -1)
    keep = np.ones(len(faces), bool)
    same = opposite = 0
    for group in np.flatnonzero(counts > 1):
        members = np.flatnonzero(inverse == group)
        plus = members[sign[members] > 0]
        minus = members[sign[members] < 0]
        pairs = min(len(plus), len(minus))
        opposite += pairs
        rest = plus[pairs:] if len(plus) > len(minus) else minus[pairs:]
        same += max(len(rest) - 1, 0)
        keep[members] = False
        if len(rest):
            keep[rest[0]] = True
    return faces[keep], same, opposite


def _orient(
    faces: np.ndarray, topo: EdgeTopology, labels: np.ndarray, n_comp: int
) -> tuple[np.ndarray | None, int, int]:
    """Make winding consistent per component, flipping the minority of faces.

    Requires every undirected edge to be used by exactly two faces.
    Returns (faces or None if non-orientable, faces flipped, faces in non-orientable parts).
    """
    n_faces = len(faces)
    f1, f2 = topo.first_corner // 3, topo.second_corner // 3
    same_direction = topo.inconsistent
    if not np.any(same_direction):
        return faces, 0, 0
    # double cover: node f is "face kept", node f + F is "face flipped"
    a = np.where(same_direction, f2 + n_faces, f2)
    b = np.where(same_direction, f2, f2 + n_faces)
    rows = np.concatenate([f1, f1 + n_faces])
    cols = np.concatenate([a, b])
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(2 * n_faces,) * 2)
    _, cover = connected_components(graph, directed=False)
    bad = cover[:n_faces] == cover[n_faces:]
    if np.any(bad):
        return None, 0, int(np.sum(bad))
    _, roots = np.unique(labels, return_index=True)
    flip = cover[:n_faces] != cover[roots[labels]]
    flipped_per = np.bincount(labels, weights=flip, minlength=n_comp)
    size = np.bincount(labels, minlength=n_comp)
    invert = flipped_per * 2 > size
    flip ^= invert[labels]
    out = faces.copy()
    out[flip] = out[flip][:, ::-1]
    return out, int(np.sum(flip)), 0


def _count_nested(
    vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray, n_comp: int
) -> int:
    """Number of components whose bounding box lies inside another component's box."""
    if n_comp > 2000:
        return 0
    tri = vertices[faces]
    lo = np.full((n_comp, 3), np.inf)
    hi = np.full((n_comp, 3), -np.inf)
    np.minimum.at(lo, labels, tri.min(axis=1))
    np.maximum.at(hi, labels, tri.max(axis=1))
    inside = np.all(lo[None, :, :] <= lo[:, None, :], axis=2) & np.all(
        hi[:, None, :] <= hi[None, :, :], axis=2
    )  # inside[k, j]: box k within box j
    np.fill_diagonal(inside, False)
    return int(np.sum(inside.any(axis=1)))


def _compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    used = np.zeros(len(vertices), bool)
    used[faces.ravel()] = True
    if np.all(used):
        return vertices, faces
    remap = np.cumsum(used) - 1
    return vertices[used], remap[faces]


def _closed_manifold_problems(faces: np.ndarray, n_vertices: int) -> list[str]:
    """Own edge-use count: every edge used by two faces, every directed edge once (two
    faces on an edge running the same way use one directed edge twice)."""
    topo = edge_topology(faces, n_vertices)
    problems = []
    if np.any(topo.counts == 1):
        problems.append(f"{int(np.sum(topo.counts == 1))} edges used by one face")
    if np.any(topo.counts > 2):
        problems.append(f"{int(np.sum(topo.counts > 2))} edges used by more than two faces")
    if np.any(topo.inconsistent):
        problems.append(f"{int(np.sum(topo.inconsistent))} directed edges used twice")
    return problems


# --------------------------------------------------------------------------------------------
# stages of the pipeline


def _refuse_unreadable(vertices: np.ndarray, faces: np.ndarray, cap: str,
                       obj_data: bytes | None) -> None:
    """Empty meshes, non-finite positions, faces that point nowhere, malformed polygons."""
    if len(faces) == 0 or len(vertices) == 0:
        raise MeshError(
            f"{cap} contains no triangles (it is empty, a point cloud or only lines): "
            "export the surface of a solid (faces), e.g. as STL or PLY."
        )
    if not np.all(np.isfinite(vertices)):
        bad = int(np.sum(~np.all(np.isfinite(vertices), axis=1)))
        raise MeshError(
            f"{cap} has {plural(bad, 'vertex', 'vertices')} with NaN or infinite coordinates: "
            f"{_FIX_REEXPORT}."
        )
    largest = float(np.abs(vertices).max())
    if largest > MAX_COORDINATE:
        raise MeshError(
            f"{cap} has coordinates as large as {largest:.3g}: beyond {MAX_COORDINATE:g} "
            "the squares of distances and the volume overflow. The file is most likely in "
            "the wrong units: scale it down in the program that wrote it."
        )
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise MeshError(
            f"{cap} has faces that refer to vertices that do not exist: the file is damaged; "
            f"{_FIX_REEXPORT}."
        )
    raw_repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (
        faces[:, 2] == faces[:, 0]
    )
    if obj_data is not None and np.any(raw_repeated):
        malformed = obj_malformed_polygons(obj_data)
        if malformed:
            raise MeshError(
                f"{cap} has malformed polygons: {'; '.join(malformed)}, so the surface that "
                "face stands for is unknown (any triangulation of it leaves a hole or a "
                "spike). Fix: correct those face lines so that each lists its corners once, "
                "in order around the face, or re-export the mesh."
            )


def _remove_degenerate(vertices: np.ndarray, faces: np.ndarray, diagonal: float, cap: str,
                       warns: list[str]) -> np.ndarray:
    """Drop faces with a repeated vertex; split needles (zero area, one vertex on the
    opposite edge) into their neighbour so the surface stays closed."""
    repeated = (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (
        faces[:, 2] == faces[:, 0]
    )
    n_degenerate = int(np.sum(repeated))
    faces = faces[~repeated]
    if len(faces):
        tri = vertices[faces]
        longest = np.linalg.norm(tri[:, [1, 2, 0]] - tri, axis=2).max(axis=1)
        height = face_areas2(vertices, faces) / np.maximum(longest, np.finfo(float).tiny)
        needle = height <= MERGE_TOLERANCE * diagonal
        if np.any(needle):
            faces, fixed = _split_needles(vertices, faces, needle)
            n_degenerate += fixed
    if n_degenerate:
        warns.append(
            f"{cap}: removed {plural(n_degenerate, 'degenerate face')} (zero area)."
        )
    return faces


def _remove_duplicate_faces(faces: np.ndarray, n_vertices: int, cap: str, warns: list[str]
                            ) -> tuple[np.ndarray, int]:
    """Collapse same-winding copies; cancel face pairs of opposite winding. Returns the faces
    and the number of opposite pairs removed (reported with the slivers)."""
    faces, n_same, n_opposite = _remove_duplicates(faces, n_vertices)
    if n_same:
        warns.append(f"{cap}: removed {plural(n_same, 'duplicate face')}.")
    if len(faces) == 0:
        raise MeshError(
            f"{cap} has zero volume: all its faces are degenerate or cancel out. "
            f"Check that the right file was exported; {_FIX_REEXPORT}."
        )
    return faces, n_opposite


def _drop_zero_area_pieces(vertices: np.ndarray, faces: np.ndarray
                           ) -> tuple[np.ndarray, EdgeTopology, int, np.ndarray, int, int]:
    """Drop edge-connected pieces of (nearly) no area beside the rest. Returns (faces,
    topology, components, face labels, pieces dropped, faces dropped)."""
    topo = edge_topology(faces, len(vertices))
    n_comp, labels = face_components(faces, topo)
    comp_area = np.bincount(labels, weights=face_areas2(vertices, faces), minlength=n_comp)
    sliver_comp = comp_area <= SLIVER_AREA_FRACTION * comp_area.sum()
    if not np.any(sliver_comp) or np.all(sliver_comp):
        return faces, topo, n_comp, labels, 0, 0
    drop = sliver_comp[labels]
    faces = faces[~drop]
    topo = edge_topology(faces, len(vertices))
    n_comp2, labels = face_components(faces, topo)
    return faces, topo, n_comp2, labels, int(np.sum(sliver_comp)), int(np.sum(drop))


def unwelded_share(vertices: np.ndarray, topo: EdgeTopology, diagonal: float) -> float:
    """The share of the open boundary's vertices with another one within CRACK_TOLERANCE *
    diagonal: faces whose corners nearly meet but were never joined (a mesh written
    without welding its vertices, or with rounded coordinates), not holes."""
    rim = np.unique(topo.edge_vertices[topo.counts == 1])
    if len(rim) < 2 or diagonal <= 0:
        return 0.0
    near, _ = cKDTree(vertices[rim]).query(vertices[rim], k=2)
    return float(np.mean(near[:, 1] <= CRACK_TOLERANCE * diagonal))


def _require_closed(vertices: np.ndarray, topo: EdgeTopology, diagonal: float,
                    cap: str) -> None:
    """Every edge used by exactly two faces, or a MeshError naming holes (or unwelded
    vertices) and fins."""
    n_open = int(np.sum(topo.counts == 1))
    n_nonmanifold = int(np.sum(topo.counts > 2))
    if not (n_open or n_nonmanifold):
        return
    defects = []
    fixes = []
    if n_open and unwelded_share(vertices, topo, diagonal) >= UNWELDED_SHARE:
        defects.append(
            f"its faces are not joined ({plural(n_open, 'open boundary edge')} whose "
            f"corners lie within {CRACK_TOLERANCE * diagonal:.3g} units of another face's: "
            "its vertices were never welded, or were rounded apart)"
        )
        fixes.append(
            "merge the vertices by distance (Blender: Mesh > Clean Up > Merge by Distance; "
            "MeshLab: Merge Close Vertices)"
        )
    elif n_open:
        holes = len(np.unique(open_edge_loops(topo)[1]))
        defects.append(
            f"it is not closed ({plural(n_open, 'open boundary edge')} "
            f"around {plural(holes, 'hole')})"
        )
        fixes.append(
            "fill the holes (Blender: Select > Select All by Trait > Non Manifold, then "
            "Face > Fill, or the 3D-Print Toolbox's Make Manifold; MeshLab: Close Holes)"
        )
    if n_nonmanifold:
        defects.append(
            f"it has {plural(n_nonmanifold, 'non-manifold edge')}, each used by more than "
            "two faces (internal faces, or bodies that touch along an edge)"
        )
        fixes.append(
            "delete the internal faces or join the parts into one solid with a boolean "
            "union (Blender: Select All by Trait > Interior Faces, then delete)"
        )
    raise MeshError(
        f"{cap} is not a watertight solid: {'; and '.join(defects)}. jampacked needs a "
        f"watertight, 2-manifold mesh. Fix: {'; '.join(fixes)}; then export again."
    )


def _orient_consistently(faces: np.ndarray, topo: EdgeTopology, labels: np.ndarray,
                         n_comp: int, cap: str, warns: list[str]) -> np.ndarray:
    oriented, n_flipped, n_bad = _orient(faces, topo, labels, n_comp)
    if oriented is None:
        raise MeshError(
            f"{cap} has a winding that cannot be made consistent: the surface is "
            f"non-orientable ({plural(n_bad, 'face')} lie on a Moebius-strip-like part, "
            "which has no inside). Fix: remodel that part as a closed solid; "
            f"{_FIX_REEXPORT}."
        )
    if n_flipped:
        warns.append(
            f"{cap}: flipped {plural(n_flipped, 'face')} whose winding disagreed with their "
            "neighbours."
        )
    return oriented


def _drop_zero_volume_bodies(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray,
                             n_comp: int, diagonal: float, cap: str
                             ) -> tuple[np.ndarray, np.ndarray, int, np.ndarray, int, int]:
    """Refuse a mesh of zero volume; drop bodies of (nearly) no volume beside the largest.
    Returns (faces, face labels, bodies, each body's signed volume, bodies dropped, faces
    dropped)."""
    six = signed_six_volumes(vertices, faces)
    comp_volume = np.bincount(labels, weights=six, minlength=n_comp) / 6.0
    largest = float(np.max(np.abs(comp_volume)))
    if largest <= ZERO_VOLUME_FRACTION * diagonal**3:
        raise MeshError(
            f"{cap} has zero volume (it is flat or its faces enclose nothing): jampacked "
            f"needs a solid. Fix: give the surface thickness (Blender: Solidify modifier) or "
            f"{_FIX_REEXPORT}."
        )
    sliver_comp = np.abs(comp_volume) <= SLIVER_VOLUME_FRACTION * largest
    if not np.any(sliver_comp):
        return faces, labels, n_comp, comp_volume, 0, 0
    drop = sliver_comp[labels]
    keep_labels = np.flatnonzero(~sliver_comp)
    relabel = np.full(n_comp, -1)
    relabel[keep_labels] = np.arange(len(keep_labels))
    return (faces[~drop], relabel[labels[~drop]], len(keep_labels), comp_volume[~sliver_comp],
            int(np.sum(sliver_comp)), int(np.sum(drop)))


def _require_one_body(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray,
                      n_comp: int, comp_volume: np.ndarray, role: str, cap: str) -> None:
    if n_comp <= 1:
        return
    nested = _count_nested(vertices, faces, labels, n_comp)
    vols = ", ".join(f"{abs(v):.4g}" for v in sorted(comp_volume, key=abs, reverse=True)[:5])
    nested_text = (
        f"; {plural(nested, 'body lies', 'bodies lie')} inside another (a hollow solid "
        "with an inner surface, or a part inside a part)"
        if nested
        else ""
    )
    if role == "container" and nested:
        fix = (
            "a container must be one closed surface: delete the extra surfaces (keep only "
            "the surface that bounds the space to fill)"
        )
    elif role == "container":
        fix = (
            "a container must be one closed space: pack each part on its own (export each "
            "body as its own file), or make them one space (a boolean union where they "
            "overlap; parts apart need a channel joining them)"
        )
    elif nested:
        fix = (
            "an object type must be one solid: for a hollow object delete the inner surface "
            "(it then packs and prints solid); for a part inside a part join them with a "
            "boolean union (Blender: Boolean modifier, Union)"
        )
    else:
        fix = (
            "an object type must be one solid: join the parts where they touch with a "
            "boolean union (Blender: Boolean modifier, Union), parts apart with a piece "
            "between them (a union alone leaves them apart), or export each body as its "
            "own file and pack them as separate types"
        )
    raise MeshError(
        f"{cap} has {n_comp} separate bodies (volumes {vols}){nested_text}. Fix: {fix}."
    )


def _verify_guarantees(vertices: np.ndarray, faces: np.ndarray, cap: str) -> None:
    """Closed, 2-manifold, consistently wound by our own edge count, and accepted by
    manifold3d."""
    problems = _closed_manifold_problems(faces, len(vertices))
    if problems:
        raise MeshError(
            f"{cap} could not be repaired into a closed 2-manifold ({'; '.join(problems)}): "
            f"{_FIX_REEXPORT}."
        )
    status = manifold_status(vertices, faces)
    if status != manifold3d.Error.NoError:
        raise MeshError(
            f"{cap} is refused by manifold3d (status {status.name}): the surface is not a "
            "valid 2-manifold solid in single precision (e.g. vertices too close together). "
            f"Fix: clean it up (Blender 3D-Print Toolbox: Make Manifold) or {_FIX_REEXPORT}."
        )


def _check_container_thickness(
    vertices: np.ndarray, faces: np.ndarray, volume: float, cap: str
) -> None:
    """Raise if the container's solid is a thin wall around a cavity (e.g. a vase shell)."""
    try:
        hull_volume = float(ConvexHull(vertices).volume)
    except QhullError:
        return
    if hull_volume <= 0:
        return
    area = float(face_areas2(vertices, faces).sum()) / 2.0
    thickness = 2.0 * volume / area  # mean wall thickness, exact for a thin slab
    size = hull_volume ** (1.0 / 3.0)
    fill = volume / hull_volume
    if thickness < THIN_WALL_THICKNESS * size and fill < THIN_WALL_HULL_FILL:
        raise MeshError(
            f"{cap}: the container's solid is a thin wall (mean thickness about "
            f"{thickness:.3g} units, {100 * thickness / size:.1f}% of its size; it fills only "
            f"{100 * fill:.0f}% of its convex hull), but the packing fills the solid, and here "
            "it needs the cavity the wall encloses. Fix: close the opening and use the inside "
            "surface as the container (Blender: separate the inner faces, Fill the rim, "
            "recalculate normals outside), or model the cavity as a closed solid."
        )


# --------------------------------------------------------------------------------------------
# the pipeline


def _refuse_far_from_origin(vertices: np.ndarray, cap: str) -> None:
    """A mesh whose distance from the origin leaves float64 too coarse for its size."""
    reach = float(np.abs(vertices).max())
    size = float(np.ptp(vertices, axis=0).max())
    step = float(np.spacing(reach))
    if size > 0 and step > FAR_PRECISION * size:
        raise MeshError(
            f"{cap} lies {reach:.3g} units from the origin but is only {size:.3g} across: "
            f"that far out, positions step by {step:.3g} units ({step / size:.2g} of its "
            "size), too coarse to place and check it. Move it near the origin in the "
            "program that wrote it (set its origin to its geometry and apply the "
            "transforms), then export it again."
        )


def check_and_repair(
    vertices: np.ndarray,
    faces: np.ndarray,
    label: str,
    role: str,
    obj_data: bytes | None = None,
) -> tuple[np.ndarray, np.ndarray, float, tuple[str, ...]]:
    """Run every check and safe repair; return (vertices, faces, volume, warnings).

    Args:
        vertices: (V, 3) float64 positions, any units and frame.
        faces: (F, 3) int64 vertex indices.
        label: what messages call the mesh (e.g. "object mesh 'a.stl'").
        role: "object" or "container" (containers also get the thin-wall check).
        obj_data: the raw bytes of an OBJ file, to name malformed polygons in errors.

    Raises:
        MeshError: a defect that cannot be repaired safely (see the module docstring).
    """
    warns: list[str] = []
    cap = _cap(label)
    _refuse_unreadable(vertices, faces, cap, obj_data)
    vertices, faces = _merge_vertices(vertices, faces)
    diagonal = float(np.linalg.norm(vertices.max(axis=0) - vertices.min(axis=0)))
    faces = _remove_degenerate(vertices, faces, diagonal, cap, warns)
    faces, n_opposite = _remove_duplicate_faces(faces, len(vertices), cap, warns)
    faces, topo, n_comp, labels, n_sliver_bodies, n_sliver_faces = _drop_zero_area_pieces(
        vertices, faces)
    if n_opposite:
        warns.append(
            f"{cap}: removed {plural(n_opposite, 'zero-volume sliver')} (pairs of coincident "
            f"faces facing opposite ways, {plural(2 * n_opposite, 'face')} in all)."
        )
    _require_closed(vertices, topo, diagonal, cap)
    faces = _orient_consistently(faces, topo, labels, n_comp, cap, warns)
    faces, labels, n_comp, comp_volume, bodies, dropped = _drop_zero_volume_bodies(
        vertices, faces, labels, n_comp, diagonal, cap)
    n_sliver_bodies += bodies
    n_sliver_faces += dropped
    if n_sliver_bodies:
        bodies_text = plural(n_sliver_bodies, "zero-volume sliver body",
                              "zero-volume sliver bodies")
        warns.append(
            f"{cap}: removed {bodies_text} ({plural(n_sliver_faces, 'face')}) beside the "
            "main body."
        )
    _require_one_body(vertices, faces, labels, n_comp, comp_volume, role, cap)

    volume = float(comp_volume.sum())
    if volume < 0:
        faces = faces[:, ::-1].copy()
        volume = -volume
        warns.append(
            f"{cap}: the mesh was inside out (negative volume, normals pointing in); "
            "its faces were inverted."
        )
    vertices, faces = _compact(vertices, faces)
    _refuse_far_from_origin(vertices, cap)
    _verify_guarantees(vertices, faces, cap)
    if role == "container":
        _check_container_thickness(vertices, faces, volume, cap)
    volume = mesh_volume_centroid(vertices, faces)[0]
    return vertices, faces, volume, tuple(warns)
