"""Preview image of a packing: parallel cross-sections, objects coloured by type.

Frames: everything is drawn in the container frame (container units). The container is
``frame_from_file @ v_file``; a placed object is ``matrix @ local_from_file @ v_file``
(see :mod:`jampacked.core.packing`). Sections are cut with manifold3d (``Manifold.slice``),
so what is drawn is the exact mesh, not an approximation.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from jampacked.core.atomic import atomic_output, missing_folder
from jampacked.core.errors import InputError
from jampacked.core.meshes import load_mesh
from jampacked.core.packing import Packing, container_mesh
from jampacked.core.solids import to_solid

#: a container at least this many times longer along z than across its thinnest side is
#: cut across that side (a torus lying in x-z, as Y-up files have it, cut along z reads as
#: strips); others along z
THIN_RATIO = 2.0
AXES = "xyz"

#: outline and fill of the container's section
_CONTAINER_EDGE = "#7f7f7f"
_CONTAINER_FILL = "#f2f2f2"


def _transform(vertices: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """(V, 3) points through a (4, 4) homogeneous matrix."""
    return vertices @ matrix[:3, :3].T + matrix[:3, 3]


def _path(polygons: list[np.ndarray]):
    """One compound matplotlib Path from closed polygons (outer loops counter-clockwise,
    holes clockwise, as manifold3d returns them; the nonzero fill rule then leaves holes
    empty). None when there is nothing to draw."""
    from matplotlib.path import Path

    polygons = [np.asarray(p, np.float64) for p in polygons if len(p) >= 3]
    if not polygons:
        return None
    verts, codes = [], []
    for p in polygons:
        verts.append(np.vstack([p, p[:1]]))
        c = np.full(len(p) + 1, Path.LINETO, dtype=Path.code_type)
        c[0] = Path.MOVETO
        c[-1] = Path.CLOSEPOLY
        codes.append(c)
    return Path(np.concatenate(verts), np.concatenate(codes))


def section_axis(extents: np.ndarray, axis: str = "auto") -> int:
    """The axis (0, 1, 2) the preview cuts along: `axis` ("x", "y" or "z"), or for "auto" z
    unless the container's bounding-box `extents` (3,) along z are THIN_RATIO times its
    shortest (then that shortest axis)."""
    if axis != "auto":
        if axis not in AXES:
            raise InputError(f"preview axis must be auto, x, y or z, got {axis!r}")
        return AXES.index(axis)
    e = np.asarray(extents, np.float64)
    thin = int(np.argmin(e))
    return thin if e[2] >= THIN_RATIO * e[thin] else 2


def write_preview(packing: Packing, path: str | os.PathLike, *,
                  heights: Sequence[float] = (0.25, 0.5, 0.75), axis: str = "auto") -> None:
    """Write a PNG of cross-sections of `packing`, one panel per height, side by side.

    Args:
        packing: the packing; its container and type mesh files must be readable (a box
            spec container needs no file). Types without a mesh file are left out.
        path: the PNG to write (atomically: temp file in the same folder + os.replace).
        heights: section positions as fractions of the container's extent along the cut
            axis in the container frame, each strictly between 0 and 1.
        axis: the axis the sections are cut across, "x", "y" or "z", or "auto"
            (`section_axis`). Each panel shows the other two axes in order, the later
            one upwards.

    Raises:
        InputError: a height outside (0, 1), an unknown axis, or the output folder does
            not exist.
        MeshError: a mesh file named by the packing cannot be read.
    """
    heights = [float(h) for h in heights]
    if not heights or not all(0.0 < h < 1.0 for h in heights):
        raise InputError(f"preview heights must be fractions strictly between 0 and 1, got "
                         f"{heights}")
    out = os.path.abspath(os.fspath(path))
    folder = os.path.dirname(out)
    missing = missing_folder(folder)
    if missing:
        raise InputError(f"cannot write preview {out}: {missing}")

    # container in the container frame
    cmesh = container_mesh(packing, "draw")
    c_verts = _transform(cmesh.vertices, packing.frame_from_file)
    a = section_axis(c_verts.max(axis=0) - c_verts.min(axis=0), axis)
    u, w = (k for k in range(3) if k != a)  # the panel's horizontal and vertical axes
    # manifold3d slices along z: turn the cut axis into z, keeping (u, w) as (x, y); a
    # rotation (the cut axis's sign flips where the order would mirror)
    to_cut = np.eye(4)[[u, w, a, 3]]
    sign = float(np.linalg.det(to_cut[:3, :3]))
    to_cut[2] *= sign
    cut = _transform(c_verts, to_cut)
    container = to_solid(cut, cmesh.faces, double=False)
    lo, hi = cut.min(axis=0), cut.max(axis=0)

    # types in their local frame; objects placed as transformed manifolds, built lazily
    n_types = len(packing.types)
    type_solids: list = [None] * n_types
    type_verts: list = [None] * n_types
    for t, rec in enumerate(packing.types):
        if rec.path is None:
            continue
        m = load_mesh(rec.path, role="object")
        v = _transform(m.vertices, rec.local_from_file)
        type_verts[t] = v
        type_solids[t] = to_solid(v, m.faces, double=False)
    mats = to_cut @ packing.matrices()
    z_lo = np.full(packing.n, np.inf)
    z_hi = np.full(packing.n, -np.inf)
    for i in range(packing.n):
        v = type_verts[packing.type_index[i]]
        if v is None:
            continue
        z = v @ mats[i, 2, :3] + mats[i, 2, 3]
        z_lo[i], z_hi[i] = z.min(), z.max()

    # matplotlib without pyplot: no global state, no display needed (Agg)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch, PathPatch

    colours = _type_colours(n_types)
    span = np.maximum(hi - lo, 1e-12)
    panel_w = 5.0
    panel_h = float(np.clip(panel_w * span[1] / span[0], 2.5, 8.0))
    fig = Figure(figsize=(panel_w * len(heights), panel_h + 1.2), dpi=110)
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(heights), squeeze=False)[0]
    pad = 0.03 * float(span[:2].max())
    counts = np.bincount(packing.type_index, minlength=n_types) if n_types else []
    for ax, frac in zip(axes, heights, strict=True):
        at = float(c_verts[:, a].min() + frac * span[2])  # along the cut axis, as given
        z = sign * at
        cpath = _path(container.slice(z).to_polygons())
        if cpath is not None:
            ax.add_patch(PathPatch(cpath, facecolor=_CONTAINER_FILL, edgecolor=_CONTAINER_EDGE,
                                   linewidth=1.2, zorder=1))
        polys: list[list[np.ndarray]] = [[] for _ in range(n_types)]
        shown = 0
        for i in np.flatnonzero((z_lo < z) & (z_hi > z)):
            t = int(packing.type_index[i])
            solid = type_solids[t].transform(mats[i, :3, :4].tolist())
            sec = solid.slice(z).to_polygons()
            if sec:
                polys[t].extend(sec)
                shown += 1
        for t in range(n_types):
            p = _path(polys[t])
            if p is not None:
                ax.add_patch(PathPatch(p, facecolor=colours[t], edgecolor="#202020",
                                       linewidth=0.4, zorder=2))
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel(f"{AXES[u]} (container units)")
        ax.set_ylabel(f"{AXES[w]} (container units)")
        ax.set_title(f"{AXES[a]} = {at:.4g}  ({frac:.0%} along {AXES[a]}), {shown} objects cut",
                     fontsize=10)
        ax.tick_params(labelsize=8)

    density = (packing.metrics or {}).get("density")
    dens = f"density {density:.1%}" if isinstance(density, (int, float)) else "density -"
    fig.suptitle(f"{os.path.basename(packing.container_path)}: {packing.n} objects, {dens}",
                 fontsize=12)
    handles = [Patch(facecolor=_CONTAINER_FILL, edgecolor=_CONTAINER_EDGE, label="container")]
    for t, rec in enumerate(packing.types):
        label = f"{rec.name} ({int(counts[t])})"
        if type_solids[t] is None:
            label += ", not drawn: no mesh file"
        handles.append(Patch(facecolor=colours[t], edgecolor="#202020", label=label))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=9,
               frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 0.95))
    _atomic_savefig(fig, out)


def _type_colours(n: int) -> list:
    from matplotlib import colormaps

    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(n)]


def _atomic_savefig(fig, out: str) -> None:
    with atomic_output(out, "wb", suffix=".tmp.png") as f:
        fig.savefig(f, format="png")
