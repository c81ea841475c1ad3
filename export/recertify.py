"""A packing edited after it was certified is certified again before it is exported.

A packing file records the digest of the placements its certificate vouches for
(`core.packing_digest`); an export of one whose placements, frames or volumes no longer match,
or of one that says it is certified without a digest, would otherwise print whatever the file
now says (two objects in one place, one through the wall) as if it had been checked.
Frames and units: the container frame, container units.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from jampacked.core.certify import Certifier, CertifyReport
from jampacked.core.container import build_container
from jampacked.core.errors import InputError
from jampacked.core.metrics import equivalent_radius
from jampacked.core.packing_types import Packing

from .scene import PlacedScene, object_name

#: container grid cells per smallest equivalent radius where the packing records no grid
CELLS_PER_RADIUS = 4.0


def certify_edited(packing: Packing, scene: PlacedScene, clearance: float,
                   source: str | None, why: str, progress: Callable[[float, str], None],
                   check_cancel: Callable[[], None],
                   labels: Sequence[str] | None = None, refuse: bool = True) -> str:
    """Certify the packing's placements as they now are, on the real meshes; returns the
    note an export gives, or raises InputError naming what fails (overlapping objects,
    objects through the wall, gaps below the clearance). source: the packing file, for
    messages; why: why its certificate does not vouch for it (`uncertified_since`);
    progress(fraction of the check, message); check_cancel() raises Cancelled when the
    export is cancelled, between the checks; labels: each placement's name (Blender's
    objects), else they are named by index and type. refuse: False for a packing that does
    not say it is certified (written by hand or by another tool): what fails is named in
    the note, and the export goes on; where nothing fails the note is empty."""
    progress(0.0, f"certifying the packing again: {packing.n:,} objects")
    volumes = np.array([t.volume for t in packing.types], np.float64)
    spacing = packing.report.container_grid_spacing
    if not (isinstance(spacing, float) and math.isfinite(spacing) and spacing > 0):
        spacing = float(equivalent_radius(volumes.min())) / CELLS_PER_RADIUS
    cont = build_container(scene.container_vertices, scene.container_faces,
                           float(packing.container_volume), spacing)
    check_cancel()  # the grid can take seconds
    scale = float(np.abs(packing.scales).max(initial=1.0))
    max_edge = np.array([float(np.linalg.norm(v[f[:, [1, 2, 0]]] - v[f], axis=2).max())
                         for v, f in zip(scene.local, scene.type_faces, strict=True)]) * scale
    def checked(done: int, total: int) -> None:
        check_cancel()
        progress(done / max(total, 1), f"certifying the packing again: {done:,} of "
                 f"{total:,} checks")

    with Certifier(cont, scene.local, [np.asarray(f, np.int64) for f in scene.type_faces],
                   volumes, max_edge, processes=0) as certifier:
        rep = certifier.certify(np.asarray(scene.type_index, np.int64), scene.matrices,
                                clearance, progress=checked)
    where = f"the packing file {source}" if source else "the packing"
    if not rep.certified and not refuse:
        return (f"{where} {why}; certified now, its placements fail: "
                f"{_failures(packing, rep, labels)}. It was exported as it is (a union "
                "merges what overlaps); pack it to have it certified.")
    if not rep.certified:
        raise InputError(
            f"cannot export: {where} {why}, and certified again its placements fail: "
            f"{_failures(packing, rep, labels)}. Undo the edit, or pack again.")
    if not refuse:  # a packing that claims nothing and holds: nothing to say
        return ""
    gaps = f", every gap at least the clearance {clearance:g}" if clearance > 0 else ""
    return (f"{where} {why}; its {packing.n} placements were certified again before "
            f"export: no overlap, nothing outside the container{gaps}.")


def _failures(packing: Packing, rep: CertifyReport,
              labels: Sequence[str] | None = None) -> str:
    """What the certificate found, naming the worst objects (by ``labels`` where given):
    by overlap where objects overlap, else by how far a gap falls short of the clearance."""
    def name(i: int) -> str:
        return object_name(packing, i, labels)

    def count(n: int, one: str, many: str) -> str:
        return f"{n} {one if n == 1 else many}"

    found = []
    if rep.bad_pairs:
        head = count(len(rep.bad_pairs), "pair fails", "pairs fail")
        bad = set(rep.bad_pairs)
        if rep.worst_overlap > rep.tol and rep.worst_overlap_pair in bad:
            a, b = rep.worst_overlap_pair
            found.append(f"{head} (worst: {name(a)} and {name(b)} overlap by "
                         f"{rep.worst_overlap:.3g} of the smaller)")
        else:
            (a, b), short = max(rep.pair_shortfall.items(), key=lambda kv: kv[1],
                                default=(rep.bad_pairs[0], 0.0))
            found.append(f"{head} (worst: {name(a)} and {name(b)} "
                         f"{_short(short, rep, 'touch', 'are {} apart')})")
    if rep.bad_wall:
        head = count(len(rep.bad_wall), "object fails", "objects fail") + " at the wall"
        if rep.worst_outside > rep.tol and rep.worst_outside_object in rep.bad_wall:
            i = rep.worst_outside_object
            found.append(f"{head} (worst: {name(i)}, {rep.worst_outside:.3g} of it outside "
                         "the container)")
        else:
            i, short = max(rep.wall_shortfall.items(), key=lambda kv: kv[1],
                           default=(rep.bad_wall[0], 0.0))
            found.append(f"{head} (worst: {name(i)} "
                         f"{_short(short, rep, 'touches the wall', 'is {} from the wall')})")
    return "; ".join(found)


def _short(shortfall: float, rep: CertifyReport, touching: str, apart: str) -> str:
    """A gap that falls short of the clearance, said by what it is: `touching` where there
    is none (a clearance written into a packing made without one), else `apart` with the
    gap, and the shortfall."""
    gap = rep.clearance - shortfall
    if gap <= 1e-9 * max(rep.clearance, 1.0):
        return f"{touching} (the clearance is {rep.clearance:g})"
    return (apart.format(f"{gap:.3g}")
            + f" ({shortfall:.3g} under the clearance {rep.clearance:g})")
