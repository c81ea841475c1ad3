"""Peer benchmark: jampacked against rigid-body physics (Blender's Bullet) on the same scene.

    /tmp/bvenv/bin/python bench/peer_bullet.py [--scene default] [--time-cap 300] \
        [--budget 60] [--seed 1] [--out bench/results/peer_bullet.json]

Needs an interpreter with `bpy` (Blender 4.5 as a Python module) and jampacked installed.
Both sides fill the same container with the same object types (same meshes, same local
frames, same target shares) and are counted by the same exact certification
(`jampacked.core.certify.Certifier`, the one `pack()` uses):

1. jampacked: `pack()` with a time budget, in a child process (no bpy there), run first so
   the two never compete for the 2 CPU cores.
2. Bullet: a fresh Blender scene; the container is a passive rigid body with a concave
   MESH collision shape, the fruit are active rigid bodies with CONVEX_HULL shapes (the
   fruit are nearly convex, except the banana: the hull/mesh volume ratios are in the JSON).
   Fruit are poured: every few frames a batch is spawned at the highest free points of a
   lattice inside the container ("free": the fruit, randomly turned, is clear of the wall
   and of every other fruit's hull, and no fruit lies directly above it, so nothing is put
   into holes of the pile), the type furthest below its target share first and others only
   while the mix stays within TVD 0.1; gravity along the container's up axis; stepped with
   `frame_set` until no fruit fits with everything at rest (or 4 s after the last pour
   that found room), or the wall-clock cap (default 300 s: Bullet with a concave mesh
   container needs about a second of wall time per frame once 50 fruit are in).
3. Both placements are counted by `certify_placements`: objects escaped (centre outside
   the container, or more than half the volume outside), pairs overlapping beyond the
   tolerance, objects through the wall, worst overlap / outside, raw density (objects not
   escaped) and the density of the certified subset (offenders removed the way `pack()`
   removes them: the smaller object of each bad pair, each object through the wall).

Scene (--scene default): the bundled default scene, Spot the cow at 150 mm with five low-poly
fruit at equal shares (about 65 fit): few enough objects for Bullet to fill it in minutes,
and Bullet is also held to a time cap. Blender units: 1 BU = 1 cm (0.1 per container unit),
gravity 9.81 BU/s^2 (a ten times larger world; slower falls, stabler contacts), 24 fps with
10 substeps and 20 solver iterations (5 substeps let fruit sink into each other and escape).
--scene tiny is a smoke test (a 50 mm box).

Writes JSON (atomically) and a density-against-time chart beside it (.png). Timings are
wall-clock seconds on this machine (2 cores, noisy). The jampacked time is the whole
`pack()` call (load, approximate, place, certify); the Bullet time is building the Blender
scene plus the simulation (not importing bpy, not our certification afterwards).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from jampacked.core.options import CavityPassOptions
from jampacked.core.repair import mix_target, removals

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
DEFAULT_SCENE_DIR = ROOT / "core" / "data" / "default_scene"
MESHES = ROOT.parent / "shared" / "meshes"
FRUIT = ("011_banana.obj", "012_strawberry.obj", "014_lemon.obj", "015_peach.obj",
         "017_orange.obj")

#: Scenes: container (path or box spec), types, shares (None = equal), container_size
#: (largest extent, container units = mm), type_scale, up axis of the container frame.
SCENES = {
    "default": {
        "container": str(DEFAULT_SCENE_DIR / "spot.obj"),
        "types": [str(DEFAULT_SCENE_DIR / f) for f in FRUIT],
        "shares": None, "container_size": 150.0, "type_scale": 300.0, "up": (0.0, 1.0, 0.0),
        "note": "the bundled default scene (jampacked pack default): Spot the cow, 150 mm, "
                "five low-poly YCB fruit at 30% of life size, equal shares",
    },
    "tiny": {  # a smoke scene: a few fruit in a box
        "container": "box:50x50x50",
        "types": [str(DEFAULT_SCENE_DIR / "012_strawberry.obj"),
                  str(DEFAULT_SCENE_DIR / "014_lemon.obj")],
        "shares": None, "container_size": None, "type_scale": 300.0, "up": (0.0, 1.0, 0.0),
        "note": "smoke scene: strawberries and lemons in a 50 mm box",
    },
}


@dataclass
class BulletParams:
    """Blender rigid body settings of the peer run (recorded in the JSON)."""

    unit_scale: float = 0.1  # Blender units per container unit: 1 BU = 1 cm for a mm scene
    gravity: float = 9.81  # BU/s^2 along -up (so the scene falls like a 10x larger world)
    fps: int = 24
    substeps_per_frame: int = 10  # 240 Hz
    solver_iterations: int = 20
    use_split_impulse: bool = False
    friction: float = 0.5  # Blender's default, fruit and container
    restitution: float = 0.0  # Blender's default
    linear_damping: float = 0.04  # Blender's defaults
    angular_damping: float = 0.1
    collision_margin: float = 0.04  # BU, Blender's default (embedded in the convex hulls)
    use_deactivation: bool = False  # Blender's default: resting fruit are simulated too
    mass_per_volume: float = 1.0  # kg per cm^3 of the scaled world: mass follows volume
    batch: int = 8  # fruit spawned at most per pour
    max_tvd: float = 0.1  # a type other than the one furthest below its share is poured only
    # while the mix (TVD by count) stays within this: the project's TVD bar (bench/run.py),
    # looser than the 0.03 jampacked's extra passes keep
    spawn_every: int = 6  # frames between pours (0.25 s of simulated time)
    spawn_spacing: float = 1.0  # spawn lattice spacing, x the smallest bounding radius
    spawn_margin: float = 1.0  # container units kept free around a spawned fruit
    rest_speed: float = 0.1  # container units per frame: everything below it is at rest
    rest_frames: int = 6  # frames in a row at rest: then a pour that finds no room ends it
    max_settle_frames: int = 96  # or this many frames (4 s) after the last pour with room


# --------------------------------------------------------------------------- geometry


@dataclass
class Geometry:
    """The scene as pack() sees it: container frame, container units (mm)."""

    container_vertices: np.ndarray  # (V,3)
    container_faces: np.ndarray  # (F,3)
    container_volume: float
    names: list[str]
    type_vertices: list[np.ndarray]  # local frame: file coords x type_scale - volume centroid
    type_faces: list[np.ndarray]
    type_volumes: np.ndarray  # (T,)
    type_max_edge: np.ndarray  # (T,)
    type_radius: np.ndarray  # (T,) bounding radius about the centroid
    shares: np.ndarray  # (T,) normalised
    local_from_file: list[np.ndarray]  # (4,4) per type, as in a Packing's TypeRecord
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    @property
    def equivalent_radius(self) -> np.ndarray:
        return (3.0 * self.type_volumes / (4.0 * np.pi)) ** (1.0 / 3.0)


def local_type_mesh(vertices_file: np.ndarray, faces: np.ndarray,
                    type_scale: float) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """(vertices, faces, volume, local_from_file) of a type in its local frame, as
    `build_type` makes it: the file's coordinates times type_scale, moved so the volume
    centroid is the origin."""
    from jampacked.core.meshes import mesh_volume_centroid

    v = np.asarray(vertices_file, np.float64) * float(type_scale)
    f = np.ascontiguousarray(faces, np.int64)
    volume, centroid = mesh_volume_centroid(v, f)
    local_from_file = np.eye(4)
    local_from_file[:3, :3] *= type_scale
    local_from_file[:3, 3] = -centroid
    return np.ascontiguousarray(v - centroid), f, float(volume), local_from_file


def make_geometry(container_vertices: np.ndarray, container_faces: np.ndarray,
                  types: Sequence[tuple[np.ndarray, np.ndarray]], type_scale: float = 1.0,
                  shares: Sequence[float] | None = None, names: Sequence[str] | None = None,
                  up: Sequence[float] = (0.0, 1.0, 0.0)) -> Geometry:
    """Geometry from arrays: the container already in the container frame, the types in file
    coordinates (moved to their local frames here)."""
    from jampacked.core.meshes import mesh_volume_centroid

    cv = np.ascontiguousarray(container_vertices, np.float64)
    cf = np.ascontiguousarray(container_faces, np.int64)
    c_volume, _ = mesh_volume_centroid(cv, cf)
    tv, tf, vols, lff = [], [], [], []
    for v, f in types:
        lv, lf, vol, m = local_type_mesh(v, f, type_scale)
        tv.append(lv)
        tf.append(lf)
        vols.append(vol)
        lff.append(m)
    q = np.ones(len(types)) if shares is None else np.asarray(shares, np.float64)
    max_edge = np.array([float(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=2).max())
                         for v, f in zip(tv, tf, strict=True)])
    up_v = np.asarray(up, np.float64)
    return Geometry(
        container_vertices=cv, container_faces=cf, container_volume=float(c_volume),
        names=list(names) if names is not None else [f"type{i}" for i in range(len(types))],
        type_vertices=tv, type_faces=tf, type_volumes=np.array(vols),
        type_max_edge=max_edge,
        type_radius=np.array([float(np.sqrt((v ** 2).sum(axis=1)).max()) for v in tv]),
        shares=q / q.sum(), local_from_file=lff, up=up_v / np.linalg.norm(up_v))


def load_geometry(spec: dict) -> Geometry:
    """Load a scene of SCENES the way pack() loads it (same scaling, same local frames)."""
    from jampacked.core.meshes import box_mesh, load_mesh, parse_box_spec

    box = parse_box_spec(spec["container"])
    cmesh = box_mesh(box) if box is not None else load_mesh(spec["container"], role="container")
    s_c = 1.0
    if spec.get("container_size") is not None:
        s_c = float(spec["container_size"]) / float(cmesh.extents.max())
    meshes = [load_mesh(t, role="object") for t in spec["types"]]
    names = [Path(t).stem.split("_", 1)[-1] for t in spec["types"]]
    return make_geometry(cmesh.vertices * s_c, cmesh.faces,
                         [(m.vertices, m.faces) for m in meshes], spec["type_scale"],
                         spec.get("shares"), names, spec.get("up", (0.0, 1.0, 0.0)))


def build_certifier(geom: Geometry, grid_spacing: float | None = None):
    """(Container, Certifier) exactly as pack() builds them; grid_spacing defaults to pack's
    medium fidelity (the smallest type's equivalent radius / 4)."""
    from jampacked.core.certify import Certifier
    from jampacked.core.container import build_container

    if grid_spacing is None:
        grid_spacing = float(geom.equivalent_radius.min()) / 4.0
    cont = build_container(geom.container_vertices, geom.container_faces,
                           geom.container_volume, grid_spacing)
    cert = Certifier(cont, geom.type_vertices, geom.type_faces, geom.type_volumes,
                     geom.type_max_edge)
    return cont, cert


def hull_ratios(geom: Geometry) -> list[float]:
    """Convex hull volume / mesh volume per type (1.0 = convex)."""
    from scipy.spatial import ConvexHull

    return [float(ConvexHull(v).volume / vol)
            for v, vol in zip(geom.type_vertices, geom.type_volumes, strict=True)]


# --------------------------------------------------------------------------- counting


def winding_numbers(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Generalised winding number of a closed triangle mesh at points (M,3): 1 inside, 0
    outside (solid angles, Van Oosterom-Strackee), exact for points off the surface."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]  # (F,3,3)
    out = np.zeros(len(points))
    for k in range(0, len(points), 64):
        p = points[k:k + 64]
        d = tri[None, :, :, :] - p[:, None, None, :]  # (m,F,3,3)
        a, b, c = d[:, :, 0], d[:, :, 1], d[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("mfi,mfi->mf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("mfi,mfi->mf", a, b) * lc
               + np.einsum("mfi,mfi->mf", b, c) * la + np.einsum("mfi,mfi->mf", c, a) * lb)
        out[k:k + 64] = 2.0 * np.arctan2(det, den).sum(axis=1) / (4.0 * np.pi)
    return out


def outside_fractions(geom: Geometry, certifier, typ: np.ndarray,
                      matrices: np.ndarray) -> np.ndarray:
    """Exact volume fraction of each object outside the container (manifold3d booleans
    against the container itself, so it holds at any distance from it)."""
    from jampacked.core.exact_checks import PlacedSolids
    from jampacked.core.solids import to_solid

    scale = certifier.solids.scale  # the certifier's solids are scaled by it
    inside = to_solid(geom.container_vertices * scale, geom.container_faces, double=False)
    placed = PlacedSolids(certifier.solids, typ, matrices)
    out = np.empty(len(typ))
    for i in range(len(typ)):
        inter = (placed(i) ^ inside).volume() / scale ** 3
        out[i] = min(max(1.0 - inter / geom.type_volumes[typ[i]], 0.0), 1.0)
    return out


def _fractions_above(values: Sequence[float], cuts: Sequence[float]) -> dict:
    return {f">{c:g}": int(sum(v > c for v in values)) for c in cuts}


def certify_placements(geom: Geometry, certifier, typ: np.ndarray, matrices: np.ndarray,
                       tol: float | None = None, escape_fraction: float = 0.5) -> dict:
    """Count one placement with pack()'s certification.

    typ (N,) type indices; matrices (N,4,4) local -> container frame (rotation and
    translation, scale 1). An object has escaped when its centre is outside the container
    or more than `escape_fraction` of its volume is. The others are certified together
    (pairs and walls, tolerance `tol` = pack()'s 1e-4 of the object volume); offenders are
    then removed as pack() removes them and the rest is certified again.
    Returns a JSON-ready dict (counts, worst values, raw and certified metrics, and the
    indices of the escaped, offending and kept objects).
    """
    from jampacked.core.certify import DEFAULT_TOL
    from jampacked.core.metrics import compute_metrics

    tol = DEFAULT_TOL if tol is None else tol
    typ = np.asarray(typ, np.int64).reshape(-1)
    matrices = np.asarray(matrices, np.float64).reshape(-1, 4, 4)
    n = len(typ)
    vols = geom.type_volumes
    centres = matrices[:, :3, 3]
    wind = winding_numbers(geom.container_vertices, geom.container_faces, centres) \
        if n else np.zeros(0)
    outside = outside_fractions(geom, certifier, typ, matrices)
    escaped = (wind < 0.5) | (outside > escape_fraction)
    idx = np.flatnonzero(~escaped)
    rep = certifier.certify(typ[idx], matrices[idx], 0.0, tol)
    # per bad pair: exact intersection volume / smaller volume (the report keeps the worst)
    from jampacked.core.exact_checks import PlacedSolids

    placed = PlacedSolids(certifier.solids, typ, matrices)
    pair_ratios = []
    for i, j in rep.bad_pairs:
        a, b = idx[i], idx[j]
        pair_ratios.append(placed.overlap(a, b) / min(vols[typ[a]], vols[typ[b]]))
    wall_ratios = [float(outside[idx[i]]) for i in rep.bad_wall]
    # removed as pack() removes them: minding the mix, not below its tolerance or the mix
    # the placement had
    mix = (geom.shares, mix_target(typ[idx], geom.shares, CavityPassOptions().max_tvd))
    kept = idx[removals(typ[idx], vols, rep.bad_pairs, rep.bad_wall, *mix)[0]]
    while True:  # removal only removes violations; re-check until certified, as pack() does
        final = certifier.certify(typ[kept], matrices[kept], 0.0, tol)
        if final.certified:
            break
        kept = kept[removals(typ[kept], vols, final.bad_pairs, final.bad_wall, *mix)[0]]
    raw = compute_metrics(typ[idx], centres[idx], vols, geom.shares, geom.container_volume)
    cert = compute_metrics(typ[kept], centres[kept], vols, geom.shares, geom.container_volume)
    cuts = (1e-4, 1e-3, 1e-2, 1e-1)
    return {
        "objects": n,
        "escaped": int(escaped.sum()),
        "escaped_centre_outside": int((wind < 0.5).sum()),
        "inside": int(len(idx)),
        "overlapping_pairs": len(rep.bad_pairs),
        "overlapping_pairs_by_ratio": _fractions_above(pair_ratios, cuts),
        "median_bad_pair_overlap": float(np.median(pair_ratios)) if pair_ratios else 0.0,
        "through_wall": len(rep.bad_wall),
        "through_wall_by_ratio": _fractions_above(wall_ratios, cuts),
        "worst_overlap": float(rep.worst_overlap),
        "worst_outside": float(rep.worst_outside),
        "worst_outside_incl_escaped": float(outside.max()) if n else 0.0,
        "certified_as_is": bool(rep.certified and not escaped.any()),
        "removed": int(len(idx) - len(kept)),
        "raw": raw,  # objects not escaped, as they lie (overlaps included)
        "certified": cert,  # the certified subset
        "raw_density": raw["density"],
        "certified_density": cert["density"],
        "certificate": rep.as_dict(),
        "certificate_after_removal": final.as_dict(),
        "escaped_indices": [int(i) for i in np.flatnonzero(escaped)],
        "kept_indices": [int(i) for i in kept],
    }


# --------------------------------------------------------------------------- pouring


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,3,3) uniformly random rotations."""
    from jampacked.core.rotations import quat_to_matrix

    q = rng.normal(size=(n, 4))
    return quat_to_matrix(q / np.linalg.norm(q, axis=1, keepdims=True))


def deficit_order(counts: np.ndarray, shares: np.ndarray) -> np.ndarray:
    """Types ordered by how far they are below their target share (largest first), for the
    next object; ties go to the bigger deficit in relative terms, then the lower index."""
    total = counts.sum() + 1
    deficit = shares * total - counts
    return np.lexsort((np.arange(len(counts)), -deficit / shares, -deficit))


@dataclass
class Hulls:
    """Convex hulls of the types (local frame): what Bullet collides (CONVEX_HULL)."""

    points: list[np.ndarray]  # (P,3) hull vertices, thinned to at most `count` spread ones
    planes: list[np.ndarray]  # (F,4) outward unit normal n and offset d: n.x + d <= 0 inside
    r_in: np.ndarray  # (T,) largest sphere about the origin inside the hull
    r_out: np.ndarray  # (T,) bounding radius about the origin
    solids: list  # manifold3d hulls, for the exact check


def type_hulls(geom: Geometry, count: int = 64) -> Hulls:
    import manifold3d as m3
    from scipy.spatial import ConvexHull

    from jampacked.core.objects import _farthest_points

    pts, planes, r_in, solids = [], [], [], []
    for v in geom.type_vertices:
        h = ConvexHull(v)
        hv = v[h.vertices]
        start = int(np.argmax((hv ** 2).sum(axis=1)))
        pts.append(_farthest_points(np.roll(hv, -start, axis=0), count))
        planes.append(np.ascontiguousarray(h.equations))
        r_in.append(float(-h.equations[:, 3].max()))
        solids.append(m3.Manifold.hull_points(np.ascontiguousarray(hv, np.float64)))
    return Hulls(pts, planes, np.array(r_in), geom.type_radius.copy(), solids)


def hulls_clear(hulls: Hulls, t: int, m: np.ndarray, others_t: Sequence[int],
                others_m: Sequence[np.ndarray], margin: float) -> bool:
    """Whether hull t placed by m (4,4, container frame) keeps `margin` from the others'
    hulls. A quick test first (no thinned vertex of either hull of a pair within margin of
    the other's planes), then the exact gap (manifold3d min_gap) for pairs that pass it."""
    x = hulls.points[t] @ m[:3, :3].T + m[:3, 3]
    for u, mo in zip(others_t, others_m, strict=True):
        local = (x - mo[:3, 3]) @ mo[:3, :3]  # into the other's local frame
        if (local @ hulls.planes[u][:, :3].T + hulls.planes[u][:, 3]).max(axis=1).min() \
                < margin:
            return False
        y = hulls.points[u] @ mo[:3, :3].T + mo[:3, 3]
        local = (y - m[:3, 3]) @ m[:3, :3]
        if (local @ hulls.planes[t][:, :3].T + hulls.planes[t][:, 3]).max(axis=1).min() \
                < margin:
            return False
    if not len(others_t):
        return True
    solid = hulls.solids[t].transform(m[:3, :4].tolist())
    return all(solid.min_gap(hulls.solids[u].transform(mo[:3, :4].tolist()), 2.0 * margin)
               >= margin for u, mo in zip(others_t, others_m, strict=True))


def covered(hulls: Hulls, up: np.ndarray, c: np.ndarray, t: int, others_t: Sequence[int],
            others_m: Sequence[np.ndarray], step: float = 0.5) -> bool:
    """Whether another fruit's hull lies directly above a type-t fruit spawned at c: five
    vertical lines (through c and at half its inner radius around it) are sampled every
    `step` through each other fruit's bounding sphere and tested against its hull."""
    up = up / np.linalg.norm(up)
    a = np.cross(up, [1.0, 0.0, 0.0])
    if np.linalg.norm(a) < 0.5:
        a = np.cross(up, [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(up, a)
    h = 0.5 * float(hulls.r_in[t])
    starts = c + np.array([[0, 0, 0], h * a, -h * a, h * b, -h * b])
    for u, mo in zip(others_t, others_m, strict=True):
        centre, r = mo[:3, 3], float(hulls.r_out[u])
        d = centre - starts  # (5,3)
        along = d @ up
        off2 = (d ** 2).sum(axis=1) - along ** 2
        for i in np.flatnonzero((off2 < r * r) & (along + r > 0)):
            half = np.sqrt(r * r - off2[i])
            s = np.arange(max(along[i] - half, 0.0), along[i] + half + step, step)
            pts = starts[i] + s[:, None] * up
            local = (pts - centre) @ mo[:3, :3]
            pl = hulls.planes[u]
            if ((local @ pl[:, :3].T + pl[:, 3]).max(axis=1) < 0.0).any():
                return True
    return False


def mix_allows(counts: np.ndarray, shares: np.ndarray, t: int, max_tvd: float) -> bool:
    """Whether one more object of type t keeps the mix: t is the type furthest below its
    share, or the TVD (by count) after adding it is at most max_tvd."""
    if int(deficit_order(counts, shares)[0]) == t:
        return True
    after = counts.astype(np.float64).copy()
    after[t] += 1
    return 0.5 * float(np.abs(after / after.sum() - shares).sum()) <= max_tvd


def choose_spawns(geom: Geometry, hulls: Hulls, container, candidates: np.ndarray,
                  typ: Sequence[int], matrices: np.ndarray, counts: np.ndarray,
                  rng: np.random.Generator, batch: int, margin: float, rotations: int = 12,
                  max_tries: int = 400, max_tvd: float = 1.0) -> list[tuple[int, np.ndarray]]:
    """Pick up to `batch` spawns (type, 4x4 matrix in the container frame), each at the
    highest free candidate.

    candidates (M,3) interior points (container frame); typ (N,) and matrices (N,4,4) the
    fruit already there. Only points with no fruit directly above them are used (`covered`:
    fruit are poured onto the pile, never put into its holes). A spawn is free when its
    vertices (a random rotation, up to
    `rotations` tries) are at least `margin` inside the wall (the container's distance grid)
    and its hull keeps `margin` from the other fruit's hulls (`hulls_clear`). Each spawn is
    of the type furthest below its target share that fits anywhere (a type that fits nowhere
    is not tried again in this pour; at most max_tries rotations per type), and another type
    only while the mix stays within max_tvd (`mix_allows`). counts is updated.
    """
    from jampacked.core.kernels import sample_grid_many

    g = container.grid
    height = candidates @ geom.up
    order = np.argsort(-(height + 1e-6 * rng.random(len(candidates))))
    cand = candidates[order]
    depth = sample_grid_many(g.values, g.origin, g.spacing, cand)
    ty = [int(t) for t in typ]
    mats = [np.asarray(m, np.float64) for m in np.asarray(matrices).reshape(-1, 4, 4)]
    failed: set[int] = set()
    chosen: list[tuple[int, np.ndarray]] = []
    while len(chosen) < batch:
        spawn = None
        centres = np.array([m[:3, 3] for m in mats]).reshape(-1, 3)
        tarr = np.asarray(ty, np.int64)
        dist = np.sqrt(((cand[:, None, :] - centres[None, :, :]) ** 2).sum(axis=2))
        for t in deficit_order(counts, geom.shares):
            if t in failed or not mix_allows(counts, geom.shares, int(t), max_tvd):
                continue
            rt, rin = float(hulls.r_out[t]), float(hulls.r_in[t])
            # necessary: the inscribed spheres are apart and the inscribed sphere is inside
            ok = depth >= rin + margin
            above = np.zeros((len(cand), len(ty)), bool)
            if len(ty):
                ok &= (dist - hulls.r_in[tarr]).min(axis=1) >= rin + margin
                # fruit that may lie above a spawn point (checked exactly with `covered`)
                rise = centres @ geom.up - (cand @ geom.up)[:, None]  # (M,N)
                across = np.sqrt(np.maximum(dist ** 2 - rise ** 2, 0.0))
                above = (rise > -hulls.r_out[tarr]) & (across < hulls.r_out[tarr] + rin)
            tries = 0
            for k in np.flatnonzero(ok):
                c = cand[k]
                # poured, not placed: nothing may lie directly above the spawn point
                js = np.flatnonzero(above[k])
                if len(js) and covered(hulls, geom.up, c, int(t), [ty[j] for j in js],
                                       [mats[j] for j in js]):
                    continue
                near = np.flatnonzero(dist[k] < rt + hulls.r_out[tarr] + margin) if len(ty) \
                    else np.zeros(0, np.int64)
                deep = depth[k] >= rt + margin
                for rot in random_rotations(rng, 1 if deep and not len(near) else rotations):
                    tries += 1
                    m = np.eye(4)
                    m[:3, :3] = rot
                    m[:3, 3] = c
                    if not deep:
                        world = geom.type_vertices[t] @ rot.T + c
                        if sample_grid_many(g.values, g.origin, g.spacing, world).min() < margin:
                            continue
                    if len(near) and not hulls_clear(hulls, int(t), m, [ty[j] for j in near],
                                                     [mats[j] for j in near], margin):
                        continue
                    spawn = (int(t), m)
                    break
                if spawn is not None or tries >= max_tries:
                    break
            if spawn is not None:
                break
            failed.add(int(t))
        if spawn is None:
            break
        chosen.append(spawn)
        counts[spawn[0]] += 1
        ty.append(spawn[0])
        mats.append(spawn[1])
    return chosen


def _fruit_mesh(bpy, name: str, vertices: np.ndarray, faces: np.ndarray):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in vertices.tolist()], [], [tuple(f) for f in faces.tolist()])
    me.update()
    return me


def _set(rb, **values) -> None:
    """Set rigid body settings that differ (each change rebuilds the collision shape)."""
    for k, v in values.items():
        cur = getattr(rb, k)
        if isinstance(v, float) and abs(cur - v) <= 1e-6 * max(1.0, abs(v)):
            continue
        if cur != v:
            setattr(rb, k, v)


def _add_rigid_bodies(bpy, objects: list, kind: str) -> None:
    bpy.context.view_layer.update()  # evaluated meshes exist before the shapes are built
    with bpy.context.temp_override(active_object=objects[0], object=objects[0],
                                   selected_objects=objects, selected_editable_objects=objects):
        bpy.ops.rigidbody.objects_add(type=kind)


def run_bullet(geom: Geometry, container, params: BulletParams, seed: int, time_cap: float,
               log: Callable[[str], None] = print) -> dict:
    """Pour fruit into the container in Blender (Bullet) until full, at rest, or time_cap
    seconds of wall time. Returns the final placements (container frame) and the run's
    record (timeline, stop reason, counts). Needs bpy."""
    import bpy

    signal.signal(signal.SIGINT, signal.default_int_handler)  # importing bpy ignores Ctrl-C
    from jampacked.core.container import interior_points
    from jampacked.core.rotations import matrix_to_quat

    rng = np.random.default_rng(seed)
    s = params.unit_scale
    t0 = time.perf_counter()
    c0 = time.process_time()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.fps = params.fps
    sc.render.fps_base = 1.0
    bpy.ops.rigidbody.world_add()
    rbw = sc.rigidbody_world
    rbw.substeps_per_frame = params.substeps_per_frame
    rbw.solver_iterations = params.solver_iterations
    rbw.use_split_impulse = params.use_split_impulse
    sc.frame_start = 1
    sc.frame_end = 1_000_000
    rbw.point_cache.frame_start = 1
    rbw.point_cache.frame_end = 1_000_000
    sc.use_gravity = True
    sc.gravity = tuple((-params.gravity * geom.up).tolist())

    cme = _fruit_mesh(bpy, "container", geom.container_vertices * s, geom.container_faces)
    cob = bpy.data.objects.new("container", cme)
    sc.collection.objects.link(cob)
    _add_rigid_bodies(bpy, [cob], "PASSIVE")
    _set(cob.rigid_body, collision_shape="MESH", friction=params.friction,
         restitution=params.restitution, collision_margin=params.collision_margin)
    bpy.context.view_layer.update()

    type_meshes = [_fruit_mesh(bpy, n, v * s, f) for n, v, f in
                   zip(geom.names, geom.type_vertices, geom.type_faces, strict=True)]
    spacing = params.spawn_spacing * float(geom.type_radius.min())
    hulls = type_hulls(geom)
    candidates = interior_points(container, spacing, float(hulls.r_in.min()) + params.spawn_margin,
                                 rng)
    log(f"bullet: {len(candidates)} spawn points, spacing {spacing:.3g}")

    objects: list = []
    typ: list[int] = []
    counts = np.zeros(len(geom.names), np.int64)
    reach = float(geom.type_radius.max())
    c_lo = geom.container_vertices.min(axis=0) - reach
    c_hi = geom.container_vertices.max(axis=0) + reach
    frame = 1
    sc.frame_set(frame)
    timeline: list[dict] = []
    last_pos = np.zeros((0, 3))
    rest_run = 0  # frames in a row with every fruit at rest
    moving, max_speed = 0, None
    since_pour = params.spawn_every  # pour at once
    last_pour = frame
    stop = None
    t_spawning = 0.0

    def positions() -> np.ndarray:
        if not objects:
            return np.zeros((0, 3))
        return np.array([tuple(o.matrix_world.translation) for o in objects]) / s

    def matrices() -> np.ndarray:
        m = np.array([np.array(o.matrix_world) for o in objects]).reshape(-1, 4, 4)
        m[:, :3, 3] /= s
        return m

    def record(event: str) -> None:
        p = positions()
        inside = np.zeros(len(p), bool)
        near = np.all((p > c_lo) & (p < c_hi), axis=1)
        if near.any():
            inside[near] = winding_numbers(geom.container_vertices, geom.container_faces,
                                           p[near]) > 0.5
        vol = float(geom.type_volumes[np.asarray(typ, np.int64)[inside]].sum()) if typ else 0.0
        timeline.append({"seconds": time.perf_counter() - t0, "frame": frame,
                         "spawned": len(objects), "centre_inside": int(inside.sum()),
                         "density_centre_inside": vol / geom.container_volume,
                         "event": event})

    while True:
        now = time.perf_counter() - t0
        if now > time_cap:
            stop = f"time cap ({time_cap:g} s)"
            break
        p = positions()
        if len(p) and len(last_pos) == len(p):
            held = np.all((p > c_lo) & (p < c_hi), axis=1)  # fruit that fell away: not waited
            speed = np.sqrt(((p - last_pos) ** 2).sum(axis=1))[held]
            at_rest = speed.size == 0 or float(speed.max()) < params.rest_speed
            moving = int((speed >= params.rest_speed).sum())
            max_speed = float(speed.max()) if speed.size else 0.0
        else:
            at_rest = len(p) == 0
            moving, max_speed = len(p), None
        rest_run = rest_run + 1 if at_rest else 0
        last_pos = p
        if since_pour >= params.spawn_every:
            since_pour = 0
            ts = time.perf_counter()
            spawns = choose_spawns(geom, hulls, container, candidates, typ, matrices(), counts,
                                   rng, params.batch, params.spawn_margin,
                                   max_tvd=params.max_tvd)
            t_spawning += time.perf_counter() - ts
            if spawns:
                new = []
                for t, m in spawns:
                    ob = bpy.data.objects.new(f"{geom.names[t]}.{len(objects) + len(new)}",
                                              type_meshes[t])
                    m = m.copy()
                    m[:3, 3] *= s
                    ob.matrix_world = m.tolist()  # rows, as mathutils.Matrix takes them
                    sc.collection.objects.link(ob)
                    new.append(ob)
                _add_rigid_bodies(bpy, new, "ACTIVE")
                for ob, (t, _) in zip(new, spawns, strict=True):
                    _set(ob.rigid_body, collision_shape="CONVEX_HULL",
                         mass=params.mass_per_volume * float(geom.type_volumes[t]) * s ** 3,
                         friction=params.friction, restitution=params.restitution,
                         linear_damping=params.linear_damping,
                         angular_damping=params.angular_damping,
                         collision_margin=params.collision_margin,
                         use_deactivation=params.use_deactivation)
                    typ.append(t)
                # build the collision shapes now: a first evaluation inside frame_set can
                # miss the new meshes ("no vertices to define Convex Hull") and leave a fruit
                # without a shape
                bpy.context.view_layer.update()
                objects.extend(new)
                last_pos = positions()
                rest_run = 0
                last_pour = frame
                record("pour")
            elif rest_run >= params.rest_frames:
                stop = "full: no fruit fits (within the mix cap), all at rest"
                break
            elif frame - last_pour >= params.max_settle_frames:
                stop = (f"full: no fruit fits, still moving {params.max_settle_frames} frames "
                        "after the last pour")
                break
        frame += 1
        sc.frame_set(frame)
        since_pour += 1
        if frame % 96 == 0:
            log(f"bullet: frame {frame}, {len(objects)} fruit, {now:.1f} s")
    record(stop)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    mats = np.array([np.array(o.matrix_world) for o in objects]).reshape(-1, 4, 4)
    rot = mats[:, :3, :3]
    # orthonormalise (the sim's float32 matrices) and bring the translation to container units
    u, _, vt = np.linalg.svd(rot)
    rot = u @ vt
    out = np.tile(np.eye(4), (len(objects), 1, 1))
    out[:, :3, :3] = rot
    out[:, :3, 3] = mats[:, :3, 3] / s
    return {
        "type_index": np.asarray(typ, np.int64), "matrices": out,
        "quaternions": matrix_to_quat(rot) if len(rot) else np.zeros((0, 4)),
        "wall_seconds": wall, "cpu_seconds": cpu, "spawn_seconds": t_spawning, "frames": frame,
        "simulated_seconds": (frame - 1) / params.fps, "stopped": stop,
        "spawned": len(objects), "spawned_per_type": [int(c) for c in counts],
        "moving_at_stop": moving,  # fruit moving faster than rest_speed in the last frame
        "max_speed_at_stop": max_speed,  # container units per frame
        "spawn_points": len(candidates), "timeline": timeline,
    }


# --------------------------------------------------------------------------- jampacked


def ours_child(scene: str, seed: int, budget: float, out: Path) -> None:
    """Child process: pack() the scene and write its record and placements."""
    from jampacked.core.api import pack
    from jampacked.core.rotations import placement_matrices

    spec = SCENES[scene]
    t0 = time.perf_counter()
    p = pack(spec["container"], spec["types"], spec["shares"], seed=seed,
             container_size=spec["container_size"], type_scale=spec["type_scale"],
             time_budget=budget)
    wall = time.perf_counter() - t0
    mats = placement_matrices(p.rotations, p.translations, p.scales)
    rec = {
        "wall_seconds": wall, "seed": seed, "timings": p.timings, "metrics": p.metrics,
        "certificate": p.certificate, "params": {
            "clearance": p.inputs.clearance, "fidelity": p.report.fidelity,
            "time_budget": p.inputs.time_budget, "container_size": p.inputs.container_size,
            "type_scale": p.inputs.type_scale,
            "container_grid_spacing": p.report.container_grid_spacing,
            "stopped": p.report.stopped, "spheres_per_type": p.report.spheres_per_type,
            "repair": asdict(p.report.repair)},
        "type_index": p.type_index.tolist(), "matrices": mats.tolist(),
        "type_volumes": [t.volume for t in p.types],
        "local_from_file": [t.local_from_file.tolist() for t in p.types],
    }
    out.write_text(json.dumps(rec))


def run_ours(scene: str, seed: int, budget: float) -> dict:
    """pack() in a child process; adds the child's CPU seconds (all its threads)."""
    import resource

    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out = Path(f.name)
    try:
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--child-ours", scene, str(seed),
                        str(budget), str(out)], check=True)
        wall = time.perf_counter() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        rec = json.loads(out.read_text())
        rec["cpu_seconds"] = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        rec["process_wall_seconds"] = wall  # with the interpreter's start and imports
        return rec
    finally:
        out.unlink(missing_ok=True)


# --------------------------------------------------------------------------- output


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.floating):
        return float(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


def write_json(path: Path, data: dict) -> None:
    """Write JSON atomically (temporary file beside it, then os.replace)."""
    from jampacked.core.atomic import atomic_output

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(path, "w") as f:
        json.dump(data, f, indent=1, default=_json_default)


def _label(name: str, c: dict, seconds: float) -> str:
    return (f"{name}: {c['certified']['count']} certified, {100 * c['certified_density']:.1f}%"
            f" in {seconds:.0f} s\nspawned/placed {c['objects']}, escaped {c['escaped']}, "
            f"overlapping pairs {c['overlapping_pairs']} (worst {c['worst_overlap']:.2g}),\n"
            f"through wall {c['through_wall']}, raw density {100 * c['raw_density']:.1f}%, "
            f"TVD {c['certified']['tvd']:.3f}")


def chart(result: dict, path: Path) -> None:
    """Density against wall time, both sides, annotated with the certification counts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 5.0))
    ours, bul = result["jampacked"], result["bullet"]
    t = ours["timings"]
    m = ours["metrics"]
    xs, ys, elapsed = [], [], t["load"] + t["approximate"]
    for stage in ("phase1", "phase2", "extra"):
        elapsed += t.get(stage, 0.0)
        if f"after_{stage}" in m:
            xs.append(elapsed)
            ys.append(100 * m[f"after_{stage}"]["density"])
    stages = len(xs)
    xs.append(ours["wall_seconds"])
    ys.append(100 * ours["count"]["certified_density"])
    ax.plot(xs, ys, "-", color="tab:blue", alpha=0.5)
    ax.scatter(xs[:stages], ys[:stages], facecolors="none", edgecolors="tab:blue",
               label="jampacked after phase 1, phase 2, extra passes (before certification)")
    ax.scatter(xs[stages:], ys[stages:], color="tab:blue", s=60, zorder=3,
               label="jampacked, certified")
    ax.text(0.01, 0.99, _label("jampacked", ours["count"], ours["wall_seconds"]),
            transform=ax.transAxes, fontsize=7.5, va="top", color="tab:blue")
    tl = bul["run"]["timeline"]
    ax.plot([e["seconds"] for e in tl], [100 * e["density_centre_inside"] for e in tl], "-",
            color="tab:orange", alpha=0.6, label="Bullet while pouring (fruit with centre inside)")
    bw = bul["run"]["wall_seconds"]
    bc = bul["count"]
    ax.scatter([bw], [100 * bc["raw_density"]], facecolors="none", edgecolors="tab:orange",
               s=60, zorder=3, label="Bullet, raw (overlaps included)")
    ax.scatter([bw], [100 * bc["certified_density"]], color="tab:orange", s=60, zorder=3,
               label="Bullet, certified subset (offenders removed)")
    ax.text(0.01, 0.86, _label("Bullet", bc, bw) + f"\n{bul['run']['stopped']}, "
            f"{bul['run']['moving_at_stop']} fruit still moving",
            transform=ax.transAxes, fontsize=7.5, va="top", color="tab:orange")
    if bul["run"]["stopped"].startswith("time cap"):
        ax.axvline(bul["time_cap"], color="tab:orange", ls=":", lw=1, label="Bullet's time cap")
    ax.set_xlabel("wall time (s), 2 cores")
    ax.set_ylabel("density (% of container volume)")
    ax.set_title(f"{result['scene']}: jampacked vs Blender rigid body (Bullet), same "
                 "certification", fontsize=9)
    ax.set_xlim(left=0)
    ax.set_ylim(0, 1.45 * max(ys + [100 * bc["raw_density"]]))
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp.png")
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="default")
    ap.add_argument("--time-cap", type=float, default=300.0,
                    help="wall-clock cap of the Bullet run, seconds (default 300: Bullet needs "
                         "minutes for this scene)")
    ap.add_argument("--budget", type=float, default=60.0,
                    help="jampacked's time budget, seconds (default 60)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=RESULTS / "peer_bullet.json")
    ap.add_argument("--chart-only", action="store_true",
                    help="redraw the chart from the JSON at --out, run nothing")
    ap.add_argument("--child-ours", nargs=4, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.chart_only:
        chart(json.loads(a.out.read_text()), a.out.with_suffix(".png"))
        return 0
    if a.child_ours:
        ours_child(a.child_ours[0], int(a.child_ours[1]), float(a.child_ours[2]),
                   Path(a.child_ours[3]))
        return 0

    spec = SCENES[a.scene]
    load = {"start": os.getloadavg()}
    print(f"jampacked: pack {a.scene}, budget {a.budget:g} s, seed {a.seed}", flush=True)
    ours = run_ours(a.scene, a.seed, a.budget)
    print(f"jampacked: {ours['metrics']['count']} objects, density "
          f"{ours['metrics']['density']:.1%} in {ours['wall_seconds']:.1f} s", flush=True)

    geom = load_geometry(spec)
    # the same local frames and volumes as pack() built
    if not (np.allclose(geom.type_volumes, ours["type_volumes"], rtol=1e-9) and np.allclose(
            geom.local_from_file, ours["local_from_file"], rtol=1e-9, atol=1e-9)):
        raise SystemExit("the benchmark's type frames differ from pack()'s")
    container, certifier = build_certifier(geom, ours["params"]["container_grid_spacing"])
    t = time.perf_counter()
    ours["count"] = certify_placements(geom, certifier, np.array(ours["type_index"]),
                                       np.array(ours["matrices"]).reshape(-1, 4, 4))
    print(f"jampacked counted in {time.perf_counter() - t:.1f} s: "
          f"{ours['count']['certified']['count']} certified", flush=True)

    params = BulletParams()
    print(f"bullet: pouring, time cap {a.time_cap:g} s", flush=True)
    run = run_bullet(geom, container, params, a.seed, a.time_cap,
                     log=lambda msg: print(msg, flush=True))
    print(f"bullet: {run['spawned']} fruit in {run['wall_seconds']:.1f} s ({run['stopped']})",
          flush=True)
    load["after_bullet"] = os.getloadavg()
    t = time.perf_counter()
    count = certify_placements(geom, certifier, run["type_index"], run["matrices"])
    count_seconds = time.perf_counter() - t
    placements = {"type_index": run.pop("type_index"), "quaternions": run.pop("quaternions"),
                  "translations": run["matrices"][:, :3, 3]}
    run.pop("matrices")
    result = {
        "scene": a.scene, "scene_spec": spec,
        "machine": f"2 cores (os.cpu_count() = {os.cpu_count()}), the two sides run one "
                   "after the other; other jobs on the machine show in the load averages",
        "load_average_1_5_15min": load,
        "tolerance": "pack()'s certification: pair intersection and outside volume <= 1e-4 of "
                     "the object volume; escaped = centre outside or > 50% of volume outside",
        "types": geom.names, "shares": geom.shares, "type_volumes": geom.type_volumes,
        "container_volume": geom.container_volume,
        "hull_over_mesh_volume": dict(zip(geom.names, hull_ratios(geom), strict=True)),
        "jampacked": {
            "wall_seconds": ours["wall_seconds"], "cpu_seconds": ours["cpu_seconds"],
            "process_wall_seconds": ours["process_wall_seconds"],
            "seed": a.seed, "time_budget": a.budget,
            "timings": ours["timings"], "metrics": ours["metrics"],
            "certificate": ours["certificate"], "params": ours["params"],
            "count": ours["count"],
            "placements": {"type_index": ours["type_index"], "matrices": ours["matrices"]},
        },
        "bullet": {
            "time_cap": a.time_cap, "seed": a.seed,
            "params": {**asdict(params), "blender": _blender_version(),
                       "container_shape": "MESH (concave, passive)",
                       "fruit_shape": "CONVEX_HULL (active)"},
            "run": run, "count": count, "count_seconds": count_seconds,
            "placements": placements,
        },
    }
    result["summary"] = summary(result)
    write_json(a.out, result)
    chart(result, a.out.with_suffix(".png"))
    for name, side, secs in (("jampacked", result["jampacked"], ours["wall_seconds"]),
                             ("bullet", result["bullet"], run["wall_seconds"])):
        c = side["count"]
        print(f"{name}: {secs:.1f} s, placed {c['objects']}, escaped {c['escaped']}, "
              f"overlapping pairs {c['overlapping_pairs']} (worst {c['worst_overlap']:.3g}), "
              f"through wall {c['through_wall']} (worst {c['worst_outside']:.3g}), raw density "
              f"{c['raw_density']:.1%}, certified {c['certified']['count']} objects "
              f"{c['certified_density']:.1%}, TVD {c['certified']['tvd']:.3f}", flush=True)
    print(f"wrote {a.out} and {a.out.with_suffix('.png')}")
    return 0


def summary(result: dict) -> dict:
    """Both sides in a few numbers, and the issue's bar: more certified density in less time.
    """
    ours, bul = result["jampacked"], result["bullet"]
    tl = bul["run"]["timeline"]
    t_ours = ours["wall_seconds"]
    before = [e for e in tl if e["seconds"] <= t_ours]
    side = {}
    for name, rec, secs, cpu in (
            ("jampacked", ours, t_ours, ours["cpu_seconds"]),
            ("bullet", bul, bul["run"]["wall_seconds"], bul["run"]["cpu_seconds"])):
        c = rec["count"]
        side[name] = {
            "seconds": secs, "cpu_seconds": cpu,
            "objects": c["objects"], "escaped": c["escaped"],
            "overlapping_pairs": c["overlapping_pairs"], "through_wall": c["through_wall"],
            "worst_overlap": c["worst_overlap"], "worst_outside": c["worst_outside"],
            "raw_density": c["raw_density"], "certified_count": c["certified"]["count"],
            "certified_density": c["certified_density"], "certified_tvd": c["certified"]["tvd"],
            "certified_nni": c["certified"]["nni_mean"],
        }
    side["bullet"]["stopped"] = bul["run"]["stopped"]
    side["bullet"]["moving_at_stop"] = bul["run"]["moving_at_stop"]
    side["bullet"]["density_at_jampacked_seconds"] = (
        before[-1]["density_centre_inside"] if before else 0.0)
    side["bar_met"] = bool(
        side["jampacked"]["certified_density"] > side["bullet"]["certified_density"]
        and side["jampacked"]["seconds"] < side["bullet"]["seconds"])
    return side


def _blender_version() -> str:
    try:
        import bpy

        return bpy.app.version_string
    except ImportError:
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
