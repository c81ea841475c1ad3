"""A shaded picture of an exported mesh (matplotlib, no GPU): the print as printed, and cut
open so that what is packed inside shows.

Frame and units: the mesh's own (container frame, container units). The shell (an exported
container wall) is told from the packed objects by the container itself when it is given
(faces on or outside its surface: the objects are fused to the shell in connect mode),
else as the body whose bounding box holds every other body. Left: the whole print. Right:
the same view with the shell's near half cut away by a vertical plane through its centre,
the objects kept whole. Front-facing triangles are drawn back to front
(painter's order), lit by a key light (Lambert), an ambient term and a rim term that
outlines silhouettes: enough to see what will be printed, not a renderer.
"""

from __future__ import annotations

import os

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from jampacked.core.atomic import atomic_output
from jampacked.export.options import up_rotation

#: (elevation, azimuth) of the two views, degrees: the whole print, the cut-away
VIEWS = ((30.0, -60.0), (20.0, -60.0))
#: at most this many triangles are drawn per view (the largest are kept)
MAX_TRIANGLES = 150_000
#: shading: ambient floor, key light (Lambert) and rim weights
AMBIENT, KEY, RIM = 0.28, 0.72, 0.35
SHELL_COLOUR = np.array([0.78, 0.76, 0.72])
#: a body at least this fraction of the outer shell's size along every axis is shell too
SHELL_LIKE = 0.75
#: packed bodies' colours, repeated
BODY_COLOURS = np.array([[0.93, 0.55, 0.16], [0.95, 0.8, 0.2], [0.55, 0.78, 0.3],
                         [0.86, 0.36, 0.3], [0.96, 0.66, 0.4]])


def shade(normals: np.ndarray, eye: np.ndarray, light: np.ndarray,
          base: np.ndarray) -> np.ndarray:
    """(F, 4) RGBA of faces with unit ``normals`` (F, 3), seen from direction ``eye`` (unit,
    towards the viewer), lit from ``light`` (unit): ambient + Lambert key light + a rim term
    (strongest where a face turns away from the viewer). ``base``: (F, 3) or (3,) RGB."""
    lam = np.clip(normals @ light, 0.0, 1.0)
    rim = (1.0 - np.clip(normals @ eye, 0.0, 1.0)) ** 3
    rgb = (AMBIENT + KEY * lam)[:, None] * np.broadcast_to(base, normals.shape) \
        + RIM * rim[:, None]
    return np.column_stack([np.clip(rgb, 0.0, 1.0), np.ones(len(rgb))])


def bodies(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(F,) the connected body (sharing vertices) of every face."""
    f = np.asarray(faces, np.int64)
    rows = np.repeat(np.arange(len(f)), 3)
    # faces and vertices as one bipartite graph: faces meet through shared vertices
    n = len(f) + n_vertices
    graph = coo_matrix((np.ones(len(rows)), (rows, len(f) + f.ravel())), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return labels[: len(f)]


def shell_bodies(tri: np.ndarray, body: np.ndarray) -> np.ndarray:
    """The bodies of the shell: the body whose bounding box is largest and holds every
    other body's, and those nearly as large along every axis (a sealed shell's inner
    surface is a body of its own). Empty when no body encloses the rest."""
    ids = np.unique(body)
    if len(ids) < 2:
        return ids[:0]
    lo = np.array([tri[body == b].reshape(-1, 3).min(axis=0) for b in ids])
    hi = np.array([tri[body == b].reshape(-1, 3).max(axis=0) for b in ids])
    size = hi - lo
    k = int(np.argmax(np.prod(size, axis=1)))
    tol = 1e-6 * float(np.max(size))
    if not (np.all(lo[k] <= lo + tol) and np.all(hi[k] >= hi - tol)):
        return ids[:0]
    return ids[np.all(size >= SHELL_LIKE * size[k], axis=1)]


def container_of(packing_path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray] | None:
    """The container mesh of a packing file in its container frame ((V, 3), (F, 3)), or
    None when it cannot be read (a container from Blender, a moved file)."""
    from jampacked.core.errors import JampackedError
    from jampacked.core.packing import container_mesh, load_packing

    try:
        packing = load_packing(packing_path)
        mesh = container_mesh(packing, "draw")
    except (JampackedError, OSError):
        return None
    m = np.asarray(packing.frame_from_file, np.float64)
    return mesh.vertices @ m[:3, :3].T + m[:3, 3], np.asarray(mesh.faces, np.int64)


def on_the_wall(points: np.ndarray, container: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """(M,) True for points on or outside the container's surface (within a cell of its
    distance grid, 1/150 of its size): where a shell is, not a packed object."""
    from jampacked.core.container import container_grid
    from jampacked.core.kernels import sample_grid_many

    v, f = container
    h = float(np.ptp(v, axis=0).max()) / 150.0
    grid = container_grid(v, f, h)
    depth = sample_grid_many(grid.values, grid.origin, grid.spacing,
                             np.ascontiguousarray(points, np.float64))
    return depth < grid.spacing


def write_render(vertices: np.ndarray, faces: np.ndarray, path: str | os.PathLike,
                 title: str | None = None, up: str = "+z",
                 container: tuple[np.ndarray, np.ndarray] | None = None) -> None:
    """Render (V, 3) vertices and (F, 3) faces to a PNG at ``path`` (written atomically),
    with the axis ``up`` (e.g. "+y" for Y-up models) pointing up in the picture: the whole
    print, and the shell cut open. ``container``: the packing's container (vertices, faces;
    the mesh's frame), which tells the shell from the objects; without it the shell is the
    body around the others, and without one the whole mesh is cut."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    v = np.asarray(vertices, np.float64) @ up_rotation(up).T
    f = np.asarray(faces, np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(n, axis=1)
    body = bodies(f, len(v))
    if container is not None:
        in_shell = on_the_wall(np.asarray(vertices, np.float64)[f].mean(axis=1), container)
    else:
        in_shell = np.isin(body, shell_bodies(tri, body))
    has_shell = bool(in_shell.any())
    keep = area > 0
    if keep.sum() > MAX_TRIANGLES:
        keep &= area >= np.sort(area)[-MAX_TRIANGLES]
    tri, n, body, in_shell = tri[keep], n[keep] / area[keep, None], body[keep], in_shell[keep]
    # the packed objects in one warm colour per body (one in connect and union modes)
    base = np.where(in_shell[:, None], SHELL_COLOUR, BODY_COLOURS[body % len(BODY_COLOURS)])
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2

    fig = plt.figure(figsize=(12, 6), dpi=110)
    for k, (elev, azim) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        e, a = np.radians(elev), np.radians(azim)
        eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        show = n @ eye > 0  # back faces are hidden by the closed surfaces anyway
        if k == 1:
            # cut-away: the near half of the shell (or of everything, without a shell) goes,
            # by a vertical plane through the centre facing the viewer
            flat = np.array([eye[0], eye[1], 0.0]) / np.hypot(eye[0], eye[1])
            near = (tri.mean(axis=1) - centre) @ flat > 0
            # with the near wall gone, the far wall's inside faces the viewer
            show &= ~(near & (in_shell if has_shell else True))
        key = eye + np.array([0.0, 0.0, 0.8]) + np.cross([0.0, 0.0, 1.0], eye) * 0.5
        key /= np.linalg.norm(key)
        colours = shade(n[show], eye, key, base[show])
        # edges in the face colour hide the seams between neighbouring triangles
        poly = Poly3DCollection(tri[show], edgecolors=colours, linewidths=0.2,
                                facecolors=colours)
        ax.add_collection3d(poly)
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            setter(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
        ax.set_title("as printed" if k == 0 else "cut open", fontsize=10)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_output(path) as handle:
        fig.savefig(handle, format="png")
    plt.close(fig)
