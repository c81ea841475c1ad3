"""One body from many solids: the union, cleaned of slivers and specks, voids filled.

Frames: the caller's (the packing's container frame, container units). manifold3d does the
booleans; the arrays go straight to the writer.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import manifold3d as m3
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from jampacked.core.errors import MeshError
from jampacked.core.solids import solid_arrays

from .cleanup import (
    NEEDLE_REL,
    collapse_needles,
    degenerate_faces,
    move_vertices,
    remove_degenerate_faces,
    shared_vertices,
)
from .intersect import _morton_order, intersecting_pairs, ray_winding_numbers, winding_numbers
from .validate import merge_identical
from .weld import weld_touching

__all__ = ["SPECK_REL", "Cleaned", "UnionVolumeError", "clean_bodies", "clean_arrays",
           "crossing_pairs", "drop_specks", "loose_bodies", "union_arrays"]

#: components of a union with less volume than this fraction of its bounding box are specks
#: (where a strut grazes a surface), dropped
SPECK_REL = 1e-9
#: how much more volume than its parts a union may report before it is called wrong: unions
#: of solids that only touch come out a few millionths larger (rounding where their surfaces
#: meet), while the failures this catches (a cavity filled) are whole volumes
UNION_VOLUME_SLACK = 1e-4
#: rounds of needle collapses on the faces that fold over once rounded to float32 (each
#: round tests the whole mesh again)
NEEDLE_ROUNDS = 3
#: a face that crosses another, once the needles are gone, has its short edge collapsed when
#: that edge is at most this fraction of its longest and of the mesh's diagonal (0.03 mm
#: on 150 mm): slivers where struts or objects meet a surface, which float32 rounding folds
CROSSING_SLIVER_REL = 0.12
CROSSING_SLIVER_LEN_REL = 2e-4
#: pieces united at a time, between which a cancel is noticed (`_chunked_union`)
UNION_CHUNK = 500
#: how far (of the mesh's diagonal) `_apart` moves vertices of surfaces that touch:
#: about 16-26 float32 steps at the largest coordinates, 0.2 micrometre at 200 mm
PINCH_STEP_REL = 1e-6


class UnionVolumeError(MeshError):
    """manifold3d's union came out with more volume than its parts (``volume`` > ``parts``):
    told apart so that a caller that simplified the parts can say so (`assemble._one_body`)."""

    def __init__(self, message: str, volume: float, parts: float) -> None:
        super().__init__(message)
        self.volume = volume
        self.parts = parts


def union_arrays(pieces: list[m3.Manifold], shell: m3.Manifold | None, float32: bool = False,
                 check_cancel: Callable[[], None] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """Union of the pieces and the shell: (vertices, faces, bad faces left); see
    :func:`clean_arrays` for the bad faces. Pieces whose corners almost coincide are first
    made to touch exactly (`weld_touching`), so that faces they share fuse. The union is
    not simplified again (a printer's resolution simplifies each type before it,
    `scene.make_type_solids`): simplifying it folded faces where objects meet, and each
    simplification adds to how far the surface moves. ``check_cancel`` (which raises to
    cancel) is called between the union's chunks.

    Raises MeshError when manifold3d fails, UnionVolumeError (a MeshError) when it returns
    a wrong result (more volume than its parts); nothing is written then.
    """
    check = check_cancel or (lambda: None)
    pieces, _ = weld_touching(pieces, check)
    result = _chunked_union(pieces, check)
    if shell is not None:
        # a separate boolean: batch_boolean with a hollow shell among hundreds of pieces
        # returned the solid container (cavity filled) in manifold3d 3.x
        result = result + shell
    if result.status() != m3.Error.NoError:
        raise MeshError(f"the union failed in manifold3d ({result.status()}); nothing was "
                        "written. Check the type meshes (`jampacked validate`) and the "
                        "packing's placements (`jampacked info`); if both are sound, report "
                        "this with the packing file.")
    total = sum(p.volume() for p in pieces) + (shell.volume() if shell else 0.0)
    if result.volume() > total * (1 + UNION_VOLUME_SLACK) + 1e-9:
        raise UnionVolumeError(
            f"the union's volume ({result.volume():.6g}) exceeds the sum of its parts "
            f"({total:.6g}): manifold3d returned a wrong result; nothing was written. Check "
            "the type meshes (`jampacked validate`) and the packing's placements (`jampacked "
            "info`); if both are sound, report this with the packing file.",
            result.volume(), total)
    return clean_arrays(result, float32=float32, check_cancel=check_cancel)


def _chunked_union(pieces: list[m3.Manifold], check_cancel: Callable[[], None]
                   ) -> m3.Manifold:
    """The union of ``pieces``, added UNION_CHUNK neighbours at a time (in Morton order of
    their bounding boxes' centres) to the union so far. manifold3d holds the GIL through a
    boolean, so a Ctrl-C waited for the whole union; between chunks ``check_cancel`` runs.
    The same triangles and volume as one batch, a little slower, with a lower memory peak
    (docs/notes-export.md)."""
    if len(pieces) <= UNION_CHUNK:
        return m3.Manifold.batch_boolean(pieces, m3.OpType.Add)
    boxes = np.array([np.asarray(p.bounding_box(), np.float64) for p in pieces])
    order = _morton_order(np.ascontiguousarray(boxes[:, :3]), np.ascontiguousarray(boxes[:, 3:]),
                          np.arange(len(pieces), dtype=np.int64))
    union = None
    for start in range(0, len(order), UNION_CHUNK):
        check_cancel()
        chunk = m3.Manifold.batch_boolean(
            [pieces[i] for i in order[start:start + UNION_CHUNK]], m3.OpType.Add)
        union = chunk if union is None else union + chunk
        union.num_tri()  # manifold3d is lazy: evaluate it here, between the cancel checks
    return union


def clean_arrays(result: m3.Manifold, float32: bool = False,
                 check_cancel: Callable[[], None] | None = None
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """The result's arrays without zero-area faces (see export/cleanup.py), with the
    vertices of surfaces that only touch moved apart (`_apart`), and how many
    faces are left bad. A face that crosses another at the positions as the file stores
    them (rounded to float32 with `float32`, for an STL or PLY) is bad too: slivers from the
    booleans, a thousandth of a millimetre wide, can fold over, and manifold3d's unions
    can fold long thin faces: the needles among the faces that cross have their short
    edges collapsed. Where the local repairs cannot remove them all, manifold3d first
    simplifies by a tolerance far below any printer's resolution (1e-7 to 1e-5 of the
    size). ``check_cancel`` (which raises to cancel) is called between the steps."""
    check = check_cancel or (lambda: None)

    def cleaned(m: m3.Manifold) -> tuple[np.ndarray, np.ndarray, int]:
        v, f = solid_arrays(m)
        if len(f):
            # components of no volume first (tetrahedra where faces that coincide were
            # split differently): the repairs below would push them apart into thin voids
            # that a closed shell keeps
            v, f = drop_specks(v, f, SPECK_REL * float(np.prod(np.ptp(v, axis=0))))[:2]
        size = float(np.linalg.norm(np.ptp(v, axis=0))) if len(v) else 0.0
        v, f, left = remove_degenerate_faces(v, f, float32=float32,
                                             max_collapse=CROSSING_SLIVER_LEN_REL * size)
        check()
        if left > 0 or len(f) == 0:
            return v, f, left
        # positions as the file stores them; those that coincide are one vertex there, as
        # the validator merges them when it reads the file back
        stored = v.astype(np.float32).astype(np.float64) if float32 else v
        _, remap = merge_identical(stored)
        step = PINCH_STEP_REL * float(np.linalg.norm(np.ptp(v, axis=0)))
        known = None  # the crossing pairs at v, f when already counted
        shared = shared_vertices(remap)
        if len(shared):
            v, known = _apart(v, f, shared, step, float32, check)
        # needles first; then, among faces that still cross, slivers whose short edge is
        # far below a printer's resolution
        reach = CROSSING_SLIVER_LEN_REL * float(np.linalg.norm(np.ptp(v, axis=0)))
        for rel, length in ((NEEDLE_REL, np.inf), (CROSSING_SLIVER_REL, reach)):
            for _ in range(NEEDLE_ROUNDS):
                pairs, left = known or crossing_pairs(v, f, float32, check)
                known = None
                if left == 0:
                    return v, f, 0
                f, collapsed = collapse_needles(v, f, pairs, rel=rel, max_length=length,
                                                float32=float32)
                if collapsed == 0:
                    known = (pairs, left)  # f is as it was
                    break
        pairs, left = known or crossing_pairs(v, f, float32, check)
        if left > 0:
            # surfaces that touch without sharing a vertex (an edge on a face: a cube turned
            # 45 degrees against another): the faces' vertices moved apart as pinches are
            v, (pairs, left) = _apart(v, f, np.unique(f[pairs]), step, float32, check,
                                      before=(pairs, left))
        return v, f, left

    v, f, left = cleaned(result)
    if left == 0 or len(v) == 0:
        return v, f, left
    diagonal = float(np.linalg.norm(np.ptp(v, axis=0)))
    for rel in (1e-7, 1e-6, 1e-5):
        check()
        cv, cf, left_here = cleaned(result.simplify(rel * diagonal))
        if left_here == 0:
            return cv, cf, 0
    if float32:
        # far from the origin float32's step is coarse (8 micrometres at 1e5 mm), and the
        # repairs judged at float32 can break the mesh at full precision too: the mesh
        # cleaned at full precision instead, with its faces left bad once rounded, so that
        # the caller can tell that float32 alone breaks it (`io.float32_breaks`)
        v64, f64, left64 = clean_arrays(result, float32=False, check_cancel=check)
        if left64 == 0:
            check()
            return v64, f64, (len(degenerate_faces(v64, f64, float32=True))
                              + crossing_pairs(v64, f64, True, check)[1])
    return v, f, left


def _apart(v: np.ndarray, f: np.ndarray, vertices: np.ndarray, step: float, float32: bool,
           check: Callable[[], None], before: tuple[np.ndarray, int] | None = None
           ) -> tuple[np.ndarray, tuple[np.ndarray, int]]:
    """Surfaces that touch at ``vertices`` (shared positions, or the corners of faces that
    touch) moved apart by ``step``: the positions and their crossing pairs
    (:func:`crossing_pairs`).

    Each vertex moves into its own solid (`move_vertices`), which parts two solids that
    only touch. Where the booleans joined them through the contact (a neck of no width: two
    cubes that share an edge, tied by a strut) the surfaces there bound the empty space
    either side, and moving in makes them cross: those among the faces that then cross or
    touch move out instead, which gives the neck a width, when that leaves fewer crossing
    pairs. With ``before`` (the pairs at v) the positions are kept unless the move leaves
    fewer crossing pairs than those."""
    inward = move_vertices(v, f, vertices, step)
    pairs, left = crossing_pairs(inward, f, float32, check)
    best = (inward, (pairs, left))
    flip = np.intersect1d(vertices, f[pairs]) if left else pairs[:0]
    if len(flip):
        out = inward.copy()
        out[flip] = 2.0 * v[flip] - inward[flip]
        pairs_out, left_out = crossing_pairs(out, f, float32, check)
        if left_out < left:
            best = (out, (pairs_out, left_out))
    if before is not None and best[1][1] >= before[1]:
        return v, before
    return best


def crossing_pairs(v: np.ndarray, f: np.ndarray, float32: bool,
                   check_cancel: Callable[[], None] | None = None) -> tuple[np.ndarray, int]:
    """Faces that cross or touch another at full precision (a 3MF, an OBJ) and, with
    ``float32``, once rounded as an STL or PLY stores them: (their indices, the number of
    pairs). ``check_cancel`` (which raises to cancel) runs before each of the two checks."""
    faces, count = [], 0
    for rounded in (False, True) if float32 else (False,):
        if check_cancel is not None:
            check_cancel()
        stored = v.astype(np.float32).astype(np.float64) if rounded else v
        first, remap = merge_identical(stored)
        pairs, crossing, _ = intersecting_pairs(stored[first], remap[f])
        faces.append(pairs.ravel())
        count += int(crossing)
    return np.concatenate(faces), count


def _components(v: np.ndarray, f: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """The mesh's connected components by shared vertices (as manifold3d writes them):
    (count, each vertex's component, each component's signed volume)."""
    n = len(v)
    rows = np.concatenate([f[:, 0], f[:, 1]])
    cols = np.concatenate([f[:, 1], f[:, 2]])
    count, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)),
                                                   shape=(n, n)), directed=False)
    # about the box's centre: far from the origin the products about it cancel (1e-4 of
    # the volume lost at 1e5 mm)
    tri = v[f] - 0.5 * (v.min(axis=0) + v.max(axis=0))
    six = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2]))
    return count, label, np.bincount(label[f[:, 0]], six, minlength=count) / 6.0


def drop_specks(v: np.ndarray, f: np.ndarray, speck: float, fill_voids: bool = False
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Split a mesh into its connected components (by shared vertices, as manifold3d
    writes them), drop those whose |volume| <= speck, with `fill_voids` also every void
    (a component of negative volume: the inward surface of a sealed cavity), and unused
    vertices; a body inside a void filled goes with it. Returns (vertices, faces, signed
    volume of each kept component, signed volume of each void filled and of each body
    that went with one)."""
    n = len(v)
    if len(f) == 0:
        return v, f, np.zeros(0), np.zeros(0)
    count, label, volumes = _components(v, f)
    face_label = label[f[:, 0]]
    used = np.zeros(count, bool)
    used[face_label] = True
    keep = used & (np.abs(volumes) > speck)
    filled = keep & (volumes < 0) if fill_voids else np.zeros(count, bool)
    keep &= ~filled
    # a body floating in a void that is filled (an object touching nothing in a sealed
    # cavity) would be a solid inside the solid: it goes into the fill too
    nested = _inside_filled(v, f, face_label, keep & (volumes > 0), filled)
    keep &= ~nested
    if not np.all(keep[used]) or len(np.unique(f)) < n:
        f = f[keep[face_label]]
        verts, inverse = np.unique(f, return_inverse=True)
        v, f = v[verts], inverse.reshape(-1, 3)
    return v, f, volumes[keep], np.concatenate([volumes[filled], volumes[nested]])


def loose_bodies(v: np.ndarray, f: np.ndarray, anchors: np.ndarray) -> int | None:
    """How many bodies (components of positive volume, joined by shared vertices as in
    :func:`drop_specks`) hold no vertex at any of the positions ``anchors`` (a shell's
    vertices: the union keeps those it does not cut exactly, and an object never reaches
    the shell's outer surface, so a body without one touches neither the shell nor anything
    joined to it). None when no body holds one (the anchors are not this mesh's)."""
    if len(f) == 0 or len(anchors) == 0:
        return None
    count, label, volumes = _components(v, f)
    anchored = np.zeros(count, bool)
    anchored[label[np.isin(_raw_rows(v), _raw_rows(anchors))]] = True
    bodies = volumes > 0
    if not (anchored & bodies).any():
        return None
    return int(np.sum(bodies & ~anchored))


def _raw_rows(a: np.ndarray) -> np.ndarray:
    """(N,) each row of positions as its raw bytes (-0.0 made +0.0), to compare positions
    bit for bit."""
    a = np.ascontiguousarray(a, np.float64) + 0.0
    return a.view(np.dtype((np.void, 24))).ravel()


def _inside_filled(v: np.ndarray, f: np.ndarray, face_label: np.ndarray, bodies: np.ndarray,
                   filled: np.ndarray) -> np.ndarray:
    """Which components (mask over the labels) among `bodies` lie inside one of the `filled`
    voids: the winding number of a point of each (its first face's centroid) about the
    void's surface, for the bodies within the void's box."""
    out = np.zeros(len(bodies), bool)
    if not filled.any() or not bodies.any():
        return out
    order = np.argsort(face_label, kind="stable")
    starts = np.searchsorted(face_label[order], np.arange(len(bodies) + 1))
    lo = np.full((len(bodies), 3), np.inf)
    hi = np.full((len(bodies), 3), -np.inf)
    for axis in range(3):
        corner = v[f, axis]
        np.minimum.at(lo[:, axis], face_label, corner.min(axis=1))
        np.maximum.at(hi[:, axis], face_label, corner.max(axis=1))
    candidates = np.flatnonzero(bodies)
    point = v[f[order[starts[candidates]]]].mean(axis=1)
    for void in np.flatnonzero(filled):
        near = np.all((lo[void] <= lo[candidates]) & (hi[candidates] <= hi[void]), axis=1)
        if not near.any():
            continue
        surface = f[order[starts[void]:starts[void + 1]]]
        w, ok = ray_winding_numbers(point[near], v, surface)
        if not np.all(ok):
            w[~ok] = np.rint(winding_numbers(point[near][~ok], v, surface))
        out[candidates[near][w != 0]] = True
    return out


@dataclass
class Cleaned:
    """A union made ready to write: its arrays, bodies, volume and the voids filled."""

    vertices: np.ndarray
    faces: np.ndarray
    bodies: int
    volume: float
    voids_filled: int
    voids_filled_volume: float
    warnings: list[str] = field(default_factory=list)


def clean_bodies(v: np.ndarray, f: np.ndarray, *, fill_voids: bool,
                 closed_shell: bool) -> Cleaned:
    """Drop specks of no volume (where a strut grazes a surface) and, with ``fill_voids``,
    fill sealed voids, unless ``closed_shell``: a closed shell's cavity is sealed on purpose.

    A closed void inside a solid is a component of negative volume, not a body; dropping its
    surface fills it, so the print traps no resin or powder there.
    """
    speck = SPECK_REL * float(np.prod(np.ptp(v, axis=0))) if len(v) else 0.0
    v, f, volumes, filled = drop_specks(v, f, speck, fill_voids=fill_voids and not closed_shell)
    out = Cleaned(vertices=v, faces=f, bodies=int(np.sum(volumes > 0)),
                  volume=float(volumes.sum()), voids_filled=int(np.sum(filled < 0)),
                  voids_filled_volume=float(-filled.sum()) + 0.0)  # never -0.0
    voids = int(np.sum(volumes < 0))
    if voids:
        why = ("the shell is closed" if closed_shell and fill_voids
               else "filling was turned off (--keep-voids)")
        out.warnings.append(
            f"the result encloses {voids} sealed void{'s' if voids > 1 else ''} (space "
            f"shut in between objects, struts and shell), kept hollow because {why}; "
            "resin and powder printers cannot drain them.")
    return out
