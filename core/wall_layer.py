"""Phase 1's seeds with a first layer along the wall (issue 19: the wall band).

The paper seeds phase 1 on a regular lattice, which cuts the wall at random depths: the
band within one object radius of the wall ends up packed far below the inside. Here the
lattice keeps only the points beyond a first layer, and the first layer's seeds lie on the
inward offset of the wall (depth `depth`), spread by a Poisson-disk thinning to about
`spacing` apart; an object grown from such a seed may turn its flattest side to the wall.
Container frame, container units throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull, cKDTree
from scipy.spatial.transform import Rotation

from .container import Container, interior_points
from .kernels import sample_grid_many
from .metrics import equivalent_radius
from .options import WallLayerOptions
from .phases import START_SCALE
from .rotations import canonical
from .solver import Solver

#: candidate points per seed spacing along each axis, before projection and thinning
CANDIDATES_PER_SPACING = 4
#: Newton steps that move a candidate onto the offset surface
PROJECTION_STEPS = 3


@dataclass(frozen=True)
class Seeds:
    """Phase 1's seed points, in the order phase 1 grows them. Wall seeds lie on the wall's
    offset and carry their outward unit normal and an angle about it (rad); lattice seeds
    have a zero normal."""

    points: np.ndarray  # (M,3)
    normals: np.ndarray  # (M,3) unit for wall seeds, zero for lattice seeds
    spin: np.ndarray  # (M,)

    @property
    def wall(self) -> np.ndarray:
        """(M,) True for the wall seeds."""
        return np.any(self.normals != 0.0, axis=1)

    def orientation(self, i: int, flat: np.ndarray | None) -> np.ndarray | None:
        """Quaternion (w,x,y,z) turning the local unit direction `flat` of an object grown
        at seed i onto its wall normal, spun by the seed's angle; None for a lattice
        seed or without a direction."""
        if flat is None or not np.any(self.normals[i] != 0.0):
            return None
        return wall_quaternion(flat, self.normals[i], float(self.spin[i]))


def depth_gradient(container: Container, pts: np.ndarray) -> np.ndarray:
    """(M,3) gradient of the container's depth (central differences at a quarter cell):
    points into the container."""
    g = container.grid
    h = 0.25 * g.spacing
    out = np.empty_like(pts)
    for a in range(3):
        step = np.zeros(3)
        step[a] = h
        out[:, a] = (sample_grid_many(g.values, g.origin, g.spacing, pts + step)
                     - sample_grid_many(g.values, g.origin, g.spacing, pts - step)) / (2 * h)
    return out


def offset_points(container: Container, depth: float, spacing: float,
                  rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points on the surface `depth` inside the wall, about `spacing` apart (a random
    sequential Poisson-disk thinning of projected lattice points), and their outward unit
    normals. Returns ((W,3), (W,3))."""
    step = spacing / CANDIDATES_PER_SPACING
    g = container.grid
    # lattice points in a shell around the offset, a little wider than one lattice step
    pts = interior_points(container, step, max(depth - step, 0.5 * depth), rng)
    if len(pts) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    d = sample_grid_many(g.values, g.origin, g.spacing, pts)
    pts = pts[d <= depth + step]
    for _ in range(PROJECTION_STEPS):
        grad = depth_gradient(container, pts)
        norm2 = np.maximum(np.sum(grad * grad, axis=1), 1e-12)
        d = sample_grid_many(g.values, g.origin, g.spacing, pts)
        pts = pts + ((depth - d) / norm2)[:, None] * grad
    d = sample_grid_many(g.values, g.origin, g.spacing, pts)
    grad = depth_gradient(container, pts)
    norm = np.linalg.norm(grad, axis=1)
    ok = (np.abs(d - depth) < 0.25 * step) & (norm > 0.5)  # off a ridge of the distance
    pts, grad, norm = pts[ok], grad[ok], norm[ok]
    keep = poisson_disk(pts, spacing, rng.permutation(len(pts)))
    return pts[keep], -grad[keep] / norm[keep, None]


def poisson_disk(pts: np.ndarray, radius: float, order: np.ndarray) -> np.ndarray:
    """Indices of the points (M,3) kept by visiting them in `order` and keeping each one
    farther than `radius` from every point kept before (random sequential adsorption)."""
    tree = cKDTree(pts)
    blocked = np.zeros(len(pts), bool)
    kept = []
    for i in order:
        if blocked[i]:
            continue
        kept.append(int(i))
        blocked[tree.query_ball_point(pts[i], radius)] = True
    return np.asarray(kept, np.int64)


def layered_seeds(container: Container, lattice_spacing: float, min_depth: float,
                  depth: float, spacing: float, rng: np.random.Generator,
                  wall_first: bool = False) -> Seeds:
    """Wall seeds on the offset at `depth`, `spacing` apart, and the points of phase 1's
    lattice (`lattice_spacing`, at least `min_depth` deep) that lie deeper than the offset
    and farther than `spacing` from every wall seed, in random order (`wall_first`: the
    wall seeds first, each group in random order)."""
    wall, normals = offset_points(container, depth, spacing, rng)
    inner = interior_points(container, lattice_spacing, max(min_depth, depth), rng)
    if len(wall) and len(inner):
        near, _ = cKDTree(wall).query(inner, distance_upper_bound=spacing)
        inner = inner[~np.isfinite(near)]
    pts = np.concatenate([wall, inner])
    nrm = np.concatenate([normals, np.zeros_like(inner)])
    spin = rng.random(len(pts)) * 2 * np.pi
    if wall_first:
        order = np.concatenate([rng.permutation(len(wall)),
                                len(wall) + rng.permutation(len(inner))])
    else:
        order = rng.permutation(len(pts))
    return Seeds(pts[order], nrm[order], spin[order])


def flattest_direction(vertices: np.ndarray) -> np.ndarray:
    """Unit direction (local frame) of the convex hull's face plane nearest the origin: the
    side on which the object reaches least far, turned to the wall it packs most volume
    near it."""
    hull = ConvexHull(vertices)
    i = int(np.argmin(-hull.equations[:, 3]))
    n = hull.equations[i, :3]
    return n / np.linalg.norm(n)


def wall_quaternion(flat: np.ndarray, normal: np.ndarray, spin: float) -> np.ndarray:
    """(4,) unit quaternion (w,x,y,z) of the rotation that takes the local direction `flat`
    onto `normal`, then turns by `spin` (rad) about `normal`."""
    align, _ = Rotation.align_vectors(normal[None], flat[None])
    r = Rotation.from_rotvec(normal * spin) * align
    return canonical(r.as_quat()[None, [3, 0, 1, 2]])[0]


def wall_seeds(solver: Solver, shares: np.ndarray, lattice_spacing: float,
               margin: np.ndarray, options: WallLayerOptions, rng: np.random.Generator
               ) -> tuple[Seeds | None, np.ndarray | None]:
    """Phase 1's seeds and each type's flattest direction ((T,3), local frame) when
    `options.layer` is on; (None, None) otherwise (phase 1 then seeds its lattice)."""
    if not options.layer:
        return None, None
    r = float(np.sum(shares * equivalent_radius(solver.t.volume)))
    min_depth = START_SCALE * solver.t.radius.max() + solver.p.clearance + margin.max()
    seeds = layered_seeds(solver.c, lattice_spacing, min_depth,
                          max(options.depth * r, min_depth), options.spacing * r, rng,
                          options.wall_first)
    flat = (np.stack([flattest_direction(t.vertices) for t in solver.t.types])
            if options.orient else None)
    return seeds, flat
