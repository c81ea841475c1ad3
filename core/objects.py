"""Object types: a mesh in its local frame plus the approximations the solver collides.

Local frame: the file's coordinates scaled by `type_scale` and moved so the volume centroid
is the origin (container units). Each type carries
- an inner sphere packing (the paper's approximation, for penetration volumes),
- a signed distance grid of the mesh (for surface points of other objects, which the inner
  spheres miss at corners and edges),
- surface points (mesh vertices plus points along long edges, thinned by farthest-point
  sampling), tested against other objects' grids and the container's grid.
Everything derived is cached on disk, keyed by the mesh geometry and the parameters.
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from .distance import DistanceGrid, distance_grid
from .fidelity import PRESETS, Fidelity
from .mesh_geometry import face_areas2
from .meshes import mesh_volume_centroid, sample_surface
from .spheres import inner_spheres

_CACHE_VERSION = "4"  # 4: edge points where crowded vertices left edges bare

#: a mesh with more vertices than points keeps its spread vertices, plus edge points where
#: its vertices and edges are further than this many times sqrt(area / points) from them:
#: the spread vertices of fruit and scans lie closer than that, a bevelled die's crowded
#: corners leave its edges far barer (docs/notes-core.md)
SPREAD_COVER = 1.5


@dataclass(frozen=True)
class ObjectType:
    """One object type, ready for the solver. All arrays in the local frame, container units."""

    name: str
    path: str | None
    sha256: str | None
    share: float
    local_from_file: np.ndarray  # (4,4)
    vertices: np.ndarray  # (V,3)
    faces: np.ndarray  # (F,3)
    volume: float
    radius: float  # max |vertex|: bounding sphere about the origin
    grid: DistanceGrid
    sphere_centres: np.ndarray  # (S,3)
    sphere_radii: np.ndarray  # (S,)
    surface_points: np.ndarray  # (P,3)
    max_edge: float

    @property
    def equivalent_radius(self) -> float:
        """f(V) = (3V/4pi)^(1/3): radius of the sphere of equal volume.

        Computed with a power, not `metrics.equivalent_radius`'s cube root: the two differ
        in the last bit, and the contact margins' probe with a clearance takes this value,
        so a clearance packing would change with the other."""
        return float((3.0 * self.volume / (4.0 * np.pi)) ** (1.0 / 3.0))


def cache_dir() -> Path:
    """Where derived approximations are cached ($JAMPACKED_CACHE or the user cache dir)."""
    env = os.environ.get("JAMPACKED_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "jampacked"


def _farthest_points(points: np.ndarray, count: int, keep: int = 1) -> np.ndarray:
    """Farthest point sampling: the first `keep` rows of points (N,3) plus spread others,
    `count` rows in all (deterministic)."""
    if len(points) <= count:
        return points
    keep = max(1, min(keep, count))
    chosen = list(range(keep))
    d = np.full(len(points), np.inf)
    for k in chosen:
        np.minimum(d, ((points - points[k]) ** 2).sum(axis=1), out=d)
    for _ in range(count - keep):
        k = int(np.argmax(d))
        chosen.append(k)
        np.minimum(d, ((points - points[k]) ** 2).sum(axis=1), out=d)
    return points[np.asarray(chosen)]


def surface_samples(vertices: np.ndarray, faces: np.ndarray, count: int,
                    on_faces: bool = False) -> np.ndarray:
    """Surface samples (P,3): `count` spread vertices (farthest point sampling) when the
    mesh has more, then edge points where vertices and edges are still further than
    SPREAD_COVER x sqrt(area / count) from every sample; else all vertices, at least
    count / 2 spread points along long edges (and, with `on_faces`, inside the faces), then
    edge points where they are further than sqrt(area / count) (`_cover_skeleton`)."""
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges = np.unique(edges, axis=0)
    a = vertices[edges[:, 0]]
    b = vertices[edges[:, 1]]
    length = np.linalg.norm(b - a, axis=1)
    extent = float(np.ptp(vertices, axis=0).max())
    step = extent / 16.0
    extra = []
    for n in range(2, 16):
        sel = (length > (n - 1) * step) & (length <= n * step)
        if not sel.any():
            continue
        t = (np.arange(1, n) / n)[None, :, None]
        extra.append((a[sel][:, None, :] * (1 - t) + b[sel][:, None, :] * t).reshape(-1, 3))
    sel = length > 15 * step
    if sel.any():
        t = (np.arange(1, 16) / 16)[None, :, None]
        extra.append((a[sel][:, None, :] * (1 - t) + b[sel][:, None, :] * t).reshape(-1, 3))
    skeleton = np.concatenate([vertices] + extra) if extra else vertices
    spacing = np.sqrt(0.5 * float(face_areas2(vertices, faces).sum()) / count)
    if len(vertices) > count:
        start = int(np.argmax(((vertices - vertices.mean(axis=0)) ** 2).sum(axis=1)))
        chosen = _farthest_points(np.roll(vertices, -start, axis=0), count)
        return np.ascontiguousarray(_cover_skeleton(chosen, skeleton, SPREAD_COVER * spacing))
    pts = np.concatenate([skeleton, sample_surface(vertices, faces, 8 * count)]
                         ) if on_faces else skeleton
    # every vertex is kept: corners are where inner spheres miss most; vertices crowded
    # into rounded corners must not take the whole count: at least half of it is spread
    # over the edges (and faces)
    chosen = _farthest_points(pts, max(count, len(vertices) + count // 2), keep=len(vertices))
    return np.ascontiguousarray(_cover_skeleton(chosen, skeleton, spacing))


def _cover_skeleton(chosen: np.ndarray, skeleton: np.ndarray, radius: float) -> np.ndarray:
    """`chosen` (P,3) plus the skeleton's points (vertices and edge points, (S,3)) farthest
    from them, one at a time, until every skeleton point lies within `radius` of a sample.

    A contact's deepest point lies on a vertex or an edge of one of the two meshes, so the
    points must cover both: the vertices of a bevelled die, crowded into its rounded corners,
    left its long edges bare, and pairs packed edge to face overlapped unseen
    (docs/notes-core.md). A mesh whose samples already cover it is unchanged.
    """
    d = cKDTree(chosen).query(skeleton)[0] ** 2
    added = []
    r2 = radius * radius
    while len(d) and d.max() > r2:
        k = int(np.argmax(d))
        added.append(k)
        np.minimum(d, ((skeleton - skeleton[k]) ** 2).sum(axis=1), out=d)
    return np.concatenate([chosen, skeleton[added]]) if added else chosen


def point_clusters(points: np.ndarray, leaf: int = 16
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group points (P,3) into clusters of at most `leaf` nearby points by halving along the
    longest box side. Returns (order (P,) point indices cluster by cluster; balls (C,4):
    each cluster's box centre and the radius that covers its points; sizes (C,) points per
    cluster). Deterministic; frame and units those of the points."""
    order: list[np.ndarray] = []
    stack = [np.arange(len(points))]
    while stack:
        idx = stack.pop()
        if len(idx) <= leaf:
            if len(idx):
                order.append(idx)
            continue
        ext = np.ptp(points[idx], axis=0)
        idx = idx[np.argsort(points[idx, int(np.argmax(ext))], kind="stable")]
        half = len(idx) // 2
        stack += [idx[half:], idx[:half]]  # the lower half is split (and listed) first
    balls = np.zeros((len(order), 4))
    for c, idx in enumerate(order):
        q = points[idx]
        mid = 0.5 * (q.min(axis=0) + q.max(axis=0))
        balls[c, :3] = mid
        balls[c, 3] = np.sqrt(((q - mid) ** 2).sum(axis=1)).max()
    sizes = np.array([len(i) for i in order], np.int64)
    flat = np.concatenate(order) if order else np.zeros(0, np.int64)
    return flat, balls, sizes


def _geometry_key(vertices: np.ndarray, faces: np.ndarray, params: tuple) -> str:
    h = hashlib.sha256()
    h.update(_CACHE_VERSION.encode())
    h.update(np.ascontiguousarray(vertices, np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, np.int64).tobytes())
    h.update(repr(params).encode())
    return h.hexdigest()[:32]


def build_type(name: str, vertices_file: np.ndarray, faces: np.ndarray, *, path: str | None,
               sha256: str | None, share: float, type_scale: float = 1.0,
               fidelity: str | Fidelity = "medium", use_cache: bool = True,
               reach: float = 0.0) -> ObjectType:
    """Move a mesh into its local frame and build its approximations.

    vertices_file: (V,3) in file units; type_scale multiplies them into container units.
    fidelity: a preset name or a `Fidelity` (spheres, grid cells, surface points).
    reach: how far from the surface (container units; the clearance) the distance grid
    must still hold true distances. Beyond the grid's box distances are extrapolated and
    read too large (docs/notes-core.md), so the grid extends this much further.
    """
    if isinstance(fidelity, str):
        if fidelity not in PRESETS:
            raise ValueError(f"unknown fidelity {fidelity!r}")
        fidelity = PRESETS[fidelity]
    n_spheres, cells, n_points = fidelity.spheres, fidelity.grid_cells, fidelity.surface_points
    v = np.asarray(vertices_file, np.float64) * float(type_scale)
    faces = np.ascontiguousarray(faces, np.int64)
    volume, centroid = mesh_volume_centroid(v, faces)
    v = np.ascontiguousarray(v - centroid)
    local_from_file = np.eye(4)
    local_from_file[:3, :3] *= type_scale
    local_from_file[:3, 3] = -centroid
    extent = float(np.ptp(v, axis=0).max())
    spacing = extent / cells
    reach = max(float(reach), 0.0)
    key = _geometry_key(v, faces, (n_spheres, cells, n_points) + ((reach,) if reach else ()))
    cached = _load_cached(key) if use_cache else None
    if cached is None:
        grid = distance_grid(v, faces, spacing, pad=2 * spacing + reach, band=3)
        centres, radii = inner_spheres(grid, n_spheres)
        # with a clearance, a neighbour held off the middle of a large face is far from
        # every vertex and edge point, and the margin covering that gap took a large part
        # of a low-poly type's room (docs/notes-core.md): the points cover the faces too
        pts = surface_samples(v, faces, n_points, on_faces=reach > 0)
        if use_cache:
            _save_cached(key, grid, centres, radii, pts)
    else:
        grid, centres, radii, pts = cached
    edges = v[faces[:, [1, 2, 0]]] - v[faces]
    return ObjectType(
        name=name, path=path, sha256=sha256, share=float(share),
        local_from_file=local_from_file, vertices=v, faces=faces, volume=float(volume),
        radius=float(np.sqrt((v ** 2).sum(axis=1)).max()), grid=grid,
        sphere_centres=centres, sphere_radii=radii, surface_points=pts,
        max_edge=float(np.linalg.norm(edges, axis=2).max()),
    )


def _load_cached(key: str):
    p = cache_dir() / f"type-{key}.npz"
    try:
        with np.load(p) as z:
            grid = DistanceGrid(z["values"], z["origin"], float(z["spacing"]))
            return grid, z["centres"], z["radii"], z["points"]
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        return None  # a damaged cache entry is rebuilt


def _save_cached(key: str, grid: DistanceGrid, centres, radii, points) -> None:
    d = cache_dir()
    try:
        d.mkdir(parents=True, exist_ok=True)
        tmp = d / f"type-{key}.{os.getpid()}.tmp.npz"
        np.savez_compressed(tmp, values=grid.values, origin=grid.origin,
                            spacing=grid.spacing, centres=centres, radii=radii, points=points)
        os.replace(tmp, d / f"type-{key}.npz")
    except OSError:
        pass  # a cache that cannot be written only costs time
