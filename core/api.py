"""`pack()`: the one call every front end uses.

container + object types + target shares -> a certified `Packing` (container frame, container
units). Steps: load and check meshes, build approximations, placement (phase 1, place &
grow; phase 2, fill cavities; extra cavity passes: `placement`, in attempts while a time
budget lasts), certify on the real meshes and repair or remove what fails, metrics.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numba
import numpy as np

from .certify import DEFAULT_TOL, Certifier
from .container import Container, build_container
from .errors import InputError, PackingError
from .fidelity import PRESETS, Fidelity, choose_fidelity
from .margins import contact_margins
from .meshes import MeshData, box_mesh, load_mesh, parse_box_spec
from .metrics import compute_metrics
from .objects import ObjectType, build_type
from .packing import Packing, TypeRecord, matrix_to_quat, placement_matrices, quat_to_matrix
from .phases import Stop, equivalent_radius
from .placement import place
from .solver import PackState, Solver, SolverParams, TypeTable
from .spheres import sphere_coverage
from .threads import ThreadTuner

Progress = Callable[[float, str], None]
MeshSource = str | os.PathLike | MeshData


@dataclass
class PackParams:
    """Method constants (the paper's defaults). Lengths are relative to object sizes."""

    phase1_density: float = 0.5  # lattice spacing = (mean type volume / this)^(1/3)
    phase1_iterations: int = 30  # solver iterations per growth step (paper: 25-30)
    phase1_growth_steps: int = 30  # growth steps from scale 0 to 1 (the paper: 30)
    phase2_spacing: float = 0.5  # phase 2 lattice spacing, fraction of phase 1's
    phase2_iterations: int = 80  # per growth step (paper: 55-150)
    phase2_retries: int = 2  # random smaller types tried after a failure
    # overrides of the fidelity's choices (None: the fidelity decides)
    spheres: int | None = None  # inner spheres per type
    grid_cells: int | None = None  # object distance grid cells across its largest extent
    surface_points: int | None = None  # surface points per type
    container_cells: float | None = None  # container grid cells per smallest f(V)
    # contact margins beyond the clearance, in cells of the object's (the container's) grid,
    # for surfaces the grid reproduces closely or not (`core/margins.py`): each costs
    # density, too little leaves certification overlaps it cannot push apart
    safety: float = 0.025  # per object whose grid keeps its surface (smooth types)
    safety_sharp: float = 0.05  # per object with edges the grid rounds off
    wall_safety: float = 0.05  # extra wall distance, smooth container
    wall_safety_sharp: float = 0.1
    # cavity passes beyond the paper: threshold = factor * smallest f(V), lattice spacing
    # scaled by the factor too
    extra_passes: tuple[float, ...] = (0.8, 0.6, 0.5, 0.4)
    extra_retries: int = 1
    extra_rounds: int = 8  # with a time budget: rounds of extra passes while they add objects
    # with a time budget: independent attempts while the time left is at least the shortest
    # attempt so far; the densest is kept (core/placement.py)
    max_attempts: int = 8
    extra_patience: int = 60  # an extra pass ends after this many fruitless points in a row
    # extra passes add no object that pushes TVD above this. Late holes are small, and the
    # types the mix then lacks are often the big ones that no longer fit: a tighter cap
    # ends those passes with time left (fruit-in-bunny seeds 1 and 2: 53.1 / 49.9% with
    # 0.03, 54.7 / 53.4% with 0.04, 51.7 / 55.0% with 0.05: no steady gain beyond 0.04)
    extra_max_tvd: float = 0.04
    # growth steps from scale 0 to 1 in the extra passes: objects there start at the free
    # radius of their hole (scale ~0.5), and coarser steps cost fewer solver calls per try
    # (fruit-in-bunny: 22 fruit in 18 s instead of 25 in 59 s in the 0.6 pass)
    extra_growth_steps: int = 12
    extra_iterations: int = 80  # solver iterations per growth step in the extra passes
    repair_rounds: int = 3  # certify -> push apart rounds before removing offenders
    repair_margin: float = 0.01  # margin added per repair round, fraction of bounding radius
    repair_iterations: int = 100
    repair_seconds: float = 20.0  # push-apart time cap; what still fails then is removed
    k_obj: float = 1.0
    k_wall: float = 1.05
    k_rot: float = 1.0
    damping: float = 0.5
    mode: int = 0
    # time the contact tests on one thread against all of numba's and keep the faster
    # (`core/threads.py`); False: always all of them
    tune_threads: bool = True


def _load(source: MeshSource, role: str) -> MeshData:
    if isinstance(source, MeshData):
        return source
    text = os.fspath(source)
    if role == "container":
        box = parse_box_spec(text)
        if box is not None:
            return box_mesh(box)
    return load_mesh(text, role=role)


def _normalise_shares(shares: Sequence[float] | None, n: int) -> np.ndarray:
    if n == 0:
        raise InputError("no object types given: pass at least one object mesh "
                         "(CLI: --type FILE[=SHARE]).")
    if shares is None:
        return np.full(n, 1.0 / n)
    q = np.asarray(shares, np.float64)
    if q.shape != (n,):
        raise InputError(f"{len(q)} shares given for {n} object types: give one share per type.")
    if not np.all(np.isfinite(q)) or np.any(q < 0) or q.sum() <= 0:
        raise InputError(f"shares must be non-negative numbers with a positive sum, got "
                         f"{q.tolist()}.")
    return q / q.sum()


def pack(container: MeshSource, types: Sequence[MeshSource],
         shares: Sequence[float] | None = None, *, seed: int = 0, clearance: float = 0.0,
         fidelity: str = "auto", time_budget: float | None = None,
         progress: Progress | None = None, should_cancel: Callable[[], bool] | None = None,
         container_size: float | None = None, type_scale: float = 1.0,
         names: Sequence[str] | None = None, params: PackParams | None = None,
         use_cache: bool = True) -> Packing:
    """Pack object types into a container; returns a certified packing.

    container: mesh file path, "box:AxBxC" (a box centred at the origin) or MeshData.
    types: mesh file paths or MeshData, one per object type; shares: target shares by count
    (normalised; default uniform). container_size: scale the container so its largest
    bounding-box extent is this (container units, e.g. mm); type_scale multiplies the object
    files' coordinates. clearance: minimum gap between objects and to the wall (container
    units). time_budget (s) bounds placement (phases 1 and 2, after loading, approximation
    and numba's compilation); time an attempt leaves goes to new attempts, and the densest
    is kept; certification runs after it. progress(fraction,
    message) and should_cancel() are polled; cancel or the budget returns the best certified
    packing so far. Raises JampackedError subclasses on bad input.
    """
    t_start = time.perf_counter()
    params = params or PackParams()
    report = progress or (lambda f, m: None)
    if clearance < 0 or not np.isfinite(clearance):
        raise InputError(f"clearance must be >= 0 (container units), got {clearance}.")
    if type_scale <= 0 or not np.isfinite(type_scale):
        raise InputError(f"type scale must be > 0, got {type_scale}.")
    if fidelity not in ("auto", *PRESETS):
        raise InputError(f"fidelity must be auto, low, medium or high, got {fidelity!r}.")
    q = _normalise_shares(shares, len(types))
    if names is not None and len(names) != len(types):
        raise InputError(f"{len(names)} names given for {len(types)} object types.")

    # --- load
    report(0.0, "loading meshes")
    cmesh = _load(container, "container")
    frame_from_file = np.eye(4)
    if container_size is not None:
        if container_size <= 0 or not np.isfinite(container_size):
            raise InputError(f"container size must be > 0, got {container_size}.")
        frame_from_file[:3, :3] *= container_size / float(cmesh.extents.max())
    s_c = frame_from_file[0, 0]
    c_vertices = cmesh.vertices * s_c
    c_volume = cmesh.volume * s_c ** 3
    meshes = [_load(t, "object") for t in types]
    t_load = time.perf_counter()

    # --- approximate
    volumes = np.array([m.volume for m in meshes]) * type_scale ** 3
    expected = 0.5 * c_volume / float(np.sum(q * volumes))
    f_min = float(equivalent_radius(volumes.min()))
    # the container's depth decides the automatic fidelity, which decides the container
    # grid: build at medium's (or the preset's) resolution, again only if that changes
    fid = PRESETS["medium"] if fidelity == "auto" else PRESETS[fidelity]
    cont: Container = build_container(c_vertices, cmesh.faces, c_volume,
                                      f_min / fid.container_cells)
    depth = float(cont.grid.values.max())
    if depth <= f_min * 0.5 + clearance:
        raise PackingError(
            f"no object fits: the container's deepest interior point is {depth:.4g} units "
            f"from its wall, the smallest object's equivalent radius is {f_min:.4g}"
            f"{f' plus clearance {clearance:g}' if clearance else ''}. Scale the container "
            "up (--container-size) or the objects down (--type-scale).")
    if fidelity == "auto":
        local = [(m.vertices - m.vertices.mean(axis=0)) * type_scale for m in meshes]
        r_max = max(float(np.sqrt((v ** 2).sum(axis=1)).max()) for v in local)
        fid = choose_fidelity(local, expected, clearance, depth / f_min, depth / r_max)
    fid = _with_overrides(fid, params)
    if cont.grid.spacing != f_min / fid.container_cells:
        cont = build_container(c_vertices, cmesh.faces, c_volume, f_min / fid.container_cells)
    report(0.02, f"approximating {len(types)} object types ({fid.name} fidelity)")
    objtypes: list[ObjectType] = []
    for i, m in enumerate(meshes):
        name = names[i] if names is not None else (
            Path(m.path).stem if m.path else f"type{i}")
        objtypes.append(build_type(name, m.vertices, m.faces, path=m.path, sha256=m.sha256,
                                   share=float(q[i]), type_scale=type_scale, fidelity=fid,
                                   use_cache=use_cache, reach=clearance))
    # a type whose largest inscribed sphere (plus the clearance) is deeper than the container
    # fits nowhere: the grid's depth is within a cell of the true depth, the spheres' radii
    # never exceed the true inscribed radius
    depth = float(cont.grid.values.max())
    no_room = [t.name for t in objtypes if t.share > 0
               and float(t.sphere_radii.max()) + clearance > depth + cont.grid.spacing]
    if no_room:
        raise PackingError(
            f"object type{'s' if len(no_room) > 1 else ''} {', '.join(no_room)} cannot fit: "
            f"the container's deepest interior point is {depth:.4g} units from its wall, less "
            f"than the type's largest inscribed sphere{' plus the clearance' if clearance else ''}"
            ". Scale the container up (--container-size) or the objects down (--type-scale)"
            f"{', lower the clearance' if clearance else ''}, or remove the type.")
    t_approx = time.perf_counter()

    # --- placement
    table = TypeTable(objtypes)
    margins = contact_margins(objtypes, cont.grid, cont.vertices, cont.faces, params.safety,
                              params.safety_sharp, params.wall_safety,
                              params.wall_safety_sharp, clearance)
    solver_params = SolverParams(
        clearance=clearance, tol=1e-6 * f_min, k_obj=params.k_obj, k_wall=params.k_wall,
        k_rot=params.k_rot, damping=params.damping, mode=params.mode,
        wall_margin=margins.wall)
    margin = margins.objects
    Solver(cont, table, PackState(), solver_params).warm_up()
    tuner = ThreadTuner(numba.get_num_threads()) if params.tune_threads else None
    t_compile = time.perf_counter()
    # the budget bounds placement (loading, approximation and compiling come before it)
    deadline = None if time_budget is None else time.perf_counter() + float(time_budget)
    stop = Stop(deadline, should_cancel)
    s1 = (float(np.sum(q * volumes)) / params.phase1_density) ** (1 / 3)
    best, attempts = place(lambda: Solver(cont, table, PackState(), solver_params, tuner),
                           q, s1, f_min, seed, stop, margin, params, c_volume, report)
    solver, state = best.solver, best.solver.s
    t_place = time.perf_counter()

    # --- certify (never skipped, also after cancel)
    report(0.9, "certifying on the real meshes")
    state.alive[: state.n] &= (state.scale[: state.n] >= 1.0).astype(np.uint8)
    certifier = Certifier(cont, [t.vertices for t in objtypes], [t.faces for t in objtypes],
                          table.volume, np.array([t.max_edge for t in objtypes]))
    cert, repair = _certify_and_repair(
        solver, certifier, clearance, params,
        lambda: bool(stop.should_cancel is not None and stop.should_cancel()))
    t_cert = time.perf_counter()

    idx = state.alive_indices()
    if len(idx) == 0 and not stop.reason:
        gap = f", the clearance {clearance:g}" if clearance else ""
        raise PackingError(
            f"no object could be placed: the container's deepest interior point is "
            f"{depth:.4g} units from its wall, the smallest type's equivalent radius is "
            f"{f_min:.4g}{gap}, and no object fitted anywhere. Scale the container up "
            "(--container-size) or the objects down (--type-scale)"
            f"{' or lower the clearance' if clearance else ''}.")
    typ = state.typ[idx].copy()
    pos = state.pos[idx].copy()
    quat = state.quat[idx].copy()
    quat = matrix_to_quat(quat_to_matrix(quat))  # canonical sign (w >= 0), unit length
    metrics = compute_metrics(typ, pos, table.volume, q, c_volume)
    metrics.update(best.after)
    # phase times are the kept attempt's; the attempts not kept have a line of their own
    timings = {
        "load": t_load - t_start, "approximate": t_approx - t_load,
        "compile": t_compile - t_approx, **best.timings}
    if len(attempts) > 1:
        timings["other_attempts"] = t_place - t_compile - sum(best.timings.values())
    timings.update({"certify": t_cert - t_place, "total": t_cert - t_start})
    all_params = asdict(params)
    all_params.update({
        "clearance": clearance, "fidelity": fid.name, "fidelity_requested": fidelity,
        "fidelity_detail": fid.as_dict(),
        "time_budget": time_budget, "container_size": container_size,
        "type_scale": type_scale, "container_grid_spacing": cont.grid.spacing,
        "phase1_spacing": s1, "stopped": stop.reason or None,
        "spheres_per_type": [int(len(t.sphere_radii)) for t in objtypes],
        "surface_points_per_type": [int(len(t.surface_points)) for t in objtypes],
        "sphere_coverage_per_type": [
            sphere_coverage(t.grid, t.sphere_centres, t.sphere_radii) for t in objtypes],
        **best.stats, "attempts": attempts, "margins": margins.as_dict(),
        "repair": repair, "threads": None if tuner is None else tuner.as_dict(),
        "warnings": [w for m in [cmesh, *meshes] for w in m.warnings],
    })
    report(1.0, f"done: {len(idx)} objects, density {metrics['density']:.1%}")
    return Packing(
        container_path=_source_name(container, cmesh), container_sha256=cmesh.sha256,
        frame_from_file=frame_from_file, container_volume=c_volume,
        types=[TypeRecord(name=t.name, path=t.path, sha256=t.sha256, share=t.share,
                          local_from_file=t.local_from_file, volume=t.volume)
               for t in objtypes],
        type_index=typ, rotations=quat, translations=pos, scales=np.ones(len(idx)),
        params=all_params, seed=int(seed), metrics=metrics, timings=timings,
        certificate=cert,
    )


def _with_overrides(fid: Fidelity, params: PackParams) -> Fidelity:
    """The fidelity with PackParams' explicit overrides applied (benchmarks sweep these)."""
    over = {k: getattr(params, k) for k in ("spheres", "grid_cells", "surface_points",
                                              "container_cells")
            if getattr(params, k) is not None}
    if not over:
        return fid
    return replace(fid, reasons=(*fid.reasons, "overridden: " + ", ".join(
        f"{k} {v}" for k, v in over.items())), **over)


def _source_name(source: MeshSource, mesh: MeshData) -> str:
    if mesh.path:
        return str(Path(mesh.path).resolve())
    if isinstance(source, MeshData):
        return "memory:container"  # a spec, not a path: saved verbatim, never looked up
    return os.fspath(source)


def _certify_and_repair(solver: Solver, certifier: Certifier, clearance: float,
                        params: PackParams, cancelled: Callable[[], bool]
                        ) -> tuple[dict, dict]:
    """Certify; push failing objects apart one at a time (a bigger margin for that object,
    then the solver, rolled back if it cannot settle) and re-check what moved; remove what
    still fails after `repair_rounds`, after `repair_seconds` of pushing, or on cancel.
    Returns (final certificate dict, repair statistics).
    """
    s = solver.s
    stats = {"rounds": 0, "moved": 0, "removed": 0, "first": None, "timed_out": False}
    deadline = time.perf_counter() + params.repair_seconds
    subset = None
    moved_ever: set[int] = set()
    for rnd in range(params.repair_rounds + 1):
        idx = s.alive_indices()
        mats = placement_matrices(s.quat[idx], s.pos[idx], s.scale[idx])
        rep = certifier.certify(s.typ[idx], mats, clearance, DEFAULT_TOL,
                                subset=None if subset is None else np.flatnonzero(
                                    np.isin(idx, subset)))
        if stats["first"] is None:
            stats["first"] = rep.as_dict()
        bad = idx[sorted(rep.bad_objects())]
        if len(bad) == 0:
            break
        if rnd == params.repair_rounds or stats["timed_out"]:
            stats["removed"] += _remove_offenders(solver, idx, rep)
            break
        stats["rounds"] += 1
        before_pos = s.pos[: s.n].copy()
        before_q = s.quat[: s.n].copy()
        for k in bad:
            if time.perf_counter() > deadline or cancelled():
                stats["timed_out"] = True
                break
            old = s.margin[k]
            s.margin[k] = 2.0 * old + params.repair_margin * solver.t.radius[s.typ[k]]
            if not solver.resolve(np.array([k], np.int64), params.repair_iterations,
                                  rollback=True):
                s.margin[k] = old
        moved = np.flatnonzero(np.any(s.pos[: s.n] != before_pos, axis=1)
                               | np.any(s.quat[: s.n] != before_q, axis=1))
        moved_ever.update(int(m) for m in moved)
        subset = np.union1d(moved, bad)
    stats["moved"] = len(moved_ever)
    while True:  # removal only removes violations; loop in case a check was trusted wrongly
        idx = s.alive_indices()
        mats = placement_matrices(s.quat[idx], s.pos[idx], s.scale[idx])
        final = certifier.certify(s.typ[idx], mats, clearance, DEFAULT_TOL)
        if final.certified:
            return final.as_dict(), stats
        stats["removed"] += _remove_offenders(solver, idx, final)


def _remove_offenders(solver: Solver, idx: np.ndarray, rep) -> int:
    """Remove the smaller object of each failing pair and each object through the wall."""
    s = solver.s
    removed = 0
    for i, j in rep.bad_pairs:
        a, b = idx[i], idx[j]
        if s.alive[a] and s.alive[b]:
            va = solver.t.volume[s.typ[a]]
            vb = solver.t.volume[s.typ[b]]
            s.alive[b if vb <= va else a] = 0
            removed += 1
    for i in rep.bad_wall:
        if s.alive[idx[i]]:
            s.alive[idx[i]] = 0
            removed += 1
    return removed
