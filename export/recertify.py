"""A packing edited after it was certified is certified again before it is exported.

A packing file records the digest of the placements its certificate vouches for
(`core.packing_digest`); an export of one whose placements, frames or volumes no longer match
would otherwise print whatever the file now says (two objects in one place, one through the
wall) as if it had been checked. Frames and units: the container frame, container units.
"""

from __future__ import annotations

import math

import numpy as np

from jampacked.core.certify import Certifier, CertifyReport
from jampacked.core.container import build_container
from jampacked.core.errors import InputError
from jampacked.core.metrics import equivalent_radius
from jampacked.core.packing_types import Packing

from .scene import PlacedScene

#: container grid cells per smallest equivalent radius where the packing records no grid
CELLS_PER_RADIUS = 4.0


def certify_edited(packing: Packing, scene: PlacedScene, clearance: float,
                   source: str | None) -> str:
    """Certify the packing's placements as they now are, on the real meshes; returns the
    note an export gives, or raises InputError naming what fails (overlapping objects,
    objects through the wall, gaps below the clearance). source: the packing file, for
    messages."""
    volumes = np.array([t.volume for t in packing.types], np.float64)
    spacing = packing.report.container_grid_spacing
    if not (isinstance(spacing, float) and math.isfinite(spacing) and spacing > 0):
        spacing = float(equivalent_radius(volumes.min())) / CELLS_PER_RADIUS
    cont = build_container(scene.container_vertices, scene.container_faces,
                           float(packing.container_volume), spacing)
    scale = float(np.abs(packing.scales).max(initial=1.0))
    max_edge = np.array([float(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=2).max())
                         for v, f in zip(scene.local, scene.type_faces, strict=True)]) * scale
    with Certifier(cont, scene.local, [np.asarray(f, np.int64) for f in scene.type_faces],
                   volumes, max_edge) as certifier:
        rep = certifier.certify(np.asarray(scene.type_index, np.int64), scene.matrices,
                                clearance)
    where = f"the packing file {source}" if source else "the packing"
    if not rep.certified:
        raise InputError(
            f"cannot export: {where} was changed after it was certified (its certificate's "
            f"digest no longer matches its placements), and certified again they fail: "
            f"{_failures(packing, rep)}. Undo the edit, or pack again.")
    gaps = f", every gap at least the clearance {clearance:g}" if clearance > 0 else ""
    return (f"{where} was changed after it was certified; its {packing.n} placements were "
            f"certified again before export: no overlap, nothing outside the container{gaps}.")


def _failures(packing: Packing, rep: CertifyReport) -> str:
    """What the certificate found, naming the worst objects."""
    def name(i: int) -> str:
        return f"object {i} ({packing.types[packing.type_index[i]].name})"

    found = []
    if rep.bad_pairs:
        a, b = rep.worst_overlap_pair or rep.bad_pairs[0]
        found.append(f"{len(rep.bad_pairs)} pair{'s' if len(rep.bad_pairs) > 1 else ''} "
                     f"overlap{'' if len(rep.bad_pairs) > 1 else 's'} or come closer than the "
                     f"clearance (worst: {name(a)} and {name(b)}, overlapping by "
                     f"{rep.worst_overlap:.3g} of the smaller)")
    if rep.bad_wall:
        i = rep.worst_outside_object if rep.worst_outside_object is not None \
            else rep.bad_wall[0]
        found.append(f"{len(rep.bad_wall)} object{'s' if len(rep.bad_wall) > 1 else ''} "
                     f"through or too near the container's wall (worst: {name(i)}, "
                     f"{rep.worst_outside:.3g} of it outside)")
    return "; ".join(found)
