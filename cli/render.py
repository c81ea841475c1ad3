"""A shaded picture of an exported mesh (matplotlib, no GPU): two views side by side.

Frame and units: the mesh's own (container frame, container units). Front-facing
triangles are drawn back to front (painter's order) with Lambert shading from a fixed
light: enough to see what will be printed, not a renderer.
"""

from __future__ import annotations

import os

import numpy as np

from jampacked.core.atomic import atomic_output
from jampacked.export.options import up_rotation

#: (elevation, azimuth) of the two views, degrees
VIEWS = ((25.0, -60.0), (60.0, 30.0))
#: at most this many triangles are drawn per view (the largest are kept)
MAX_TRIANGLES = 150_000


def _shade(normals: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(F, 4) RGBA: a warm grey lit by ``light`` (unit vector), with an ambient floor."""
    lam = np.clip(normals @ light, 0.0, 1.0)
    base = np.array([0.86, 0.62, 0.38])
    rgb = (0.25 + 0.75 * lam)[:, None] * base
    return np.column_stack([rgb, np.ones(len(rgb))])


def write_render(vertices: np.ndarray, faces: np.ndarray, path: str | os.PathLike,
                 title: str | None = None, up: str = "+z") -> None:
    """Render (V, 3) vertices and (F, 3) faces to a PNG at ``path`` (written atomically),
    with the axis ``up`` (e.g. "+y" for Y-up models) pointing up in the picture."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    v = np.asarray(vertices, np.float64) @ up_rotation(up).T
    f = np.asarray(faces, np.int64)
    tri = v[f]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = np.linalg.norm(n, axis=1)
    keep = area > 0
    if keep.sum() > MAX_TRIANGLES:
        keep &= area >= np.sort(area)[-MAX_TRIANGLES]
    tri, n = tri[keep], n[keep] / area[keep, None]
    lo, hi = v.min(axis=0), v.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2

    fig = plt.figure(figsize=(12, 6), dpi=110)
    for k, (elev, azim) in enumerate(VIEWS):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        e, a = np.radians(elev), np.radians(azim)
        eye = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
        front = n @ eye > 0  # back faces are hidden by the closed surface anyway
        light = eye + np.array([0.0, 0.0, 0.6])
        # the collection sorts its polygons by depth itself (painter's order)
        poly = Poly3DCollection(tri[front], edgecolors="none", linewidths=0,
                                facecolors=_shade(n[front], light / np.linalg.norm(light)))
        ax.add_collection3d(poly)
        for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre, strict=True):
            setter(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_axis_off()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    with atomic_output(path) as handle:
        fig.savefig(handle, format="png")
    plt.close(fig)
