"""`pack()`: the one call every front end uses.

container + object types + target shares -> a certified `Packing` (container frame, container
units), in named stages: load (and scale) the meshes, approximate them, place (phase 1, place &
grow; phase 2, fill cavities; extra cavity passes, in attempts while a time budget lasts:
`placement`), certify on the real meshes and repair or remove what fails (`repair`), and
assemble the result.
"""

from __future__ import annotations

import contextlib
import math
import numbers
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numba
import numpy as np

from .certify import Certifier
from .cluster import AttemptJob, client_for, cluster_threads, place_on_cluster
from .container import Container, container_grid, container_on, grid_spacing
from .cost import TypeSize, check_cost, check_sizes, estimate_cost
from .errors import InputError, PackingError
from .fidelity import PRESETS, Fidelity, choose_fidelity, preset
from .margins import Margins, contact_margins
from .mesh_geometry import inner_room
from .meshes import MeshData, box_mesh, load_mesh, parse_box_spec
from .metrics import compute_metrics, equivalent_radius
from .numba_cache import COMPILE_MESSAGE, cache_is_cold
from .objects import ObjectType, build_type
from .options import FidelityOverrides, PackOptions
from .packing_digest import record_digest
from .packing_types import Packing, TypeRecord, distinct_names
from .phases import Stop
from .placement import Attempt, Snapshots, place, snapshot_metrics
from .repair import certify_and_repair
from .report import NOTE_PREFIX, AttemptSummary, PackInputs, RepairStats, RunReport
from .room import (
    OutOfReach,
    check_types_fit,
    measured_depth,
    nothing_placed_message,
    out_of_reach,
    refuse_no_room,
    refuse_too_long,
    tight_fit_spacing,
)
from .rotations import matrix_to_quat, quat_to_matrix
from .run_warnings import run_warnings, slow_certification
from .solver import PackState, Solver, SolverParams, TypeTable
from .spheres import sphere_coverage
from .threads import ThreadTuner
from .type_give_up import shares_without

Progress = Callable[[float, str], None]
Snapshot = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
MeshSource = str | os.PathLike | MeshData


def _load(source: MeshSource, role: str) -> MeshData:
    if isinstance(source, MeshData):
        return source
    if not isinstance(source, str | os.PathLike):
        what = ("the container" if role == "container"
                else "each object type")
        raise InputError(f"{what} must be a mesh file path or MeshData"
                         f"{' (or a box spec, box:WxDxH)' if role == 'container' else ''}; "
                         f"got {source!r}.")
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
    try:
        q = np.asarray(shares, np.float64)
    except (TypeError, ValueError):
        raise InputError(f"shares must be numbers, one per object type; got {shares!r}."
                         ) from None
    if q.shape != (n,):
        raise InputError(f"{len(q)} shares given for {n} object types: give one share per type.")
    if not np.all(np.isfinite(q)) or np.any(q < 0) or q.sum() <= 0:
        raise InputError(f"shares must be non-negative numbers with a positive sum, got "
                         f"{q.tolist()}.")
    if not np.isfinite(q.sum()):  # shares near the float maximum: their sum overflows
        q = q / q.max()
    return q / q.sum()


def pack(container: MeshSource, types: Sequence[MeshSource],
         shares: Sequence[float] | None = None, *, seed: int = 0, clearance: float = 0.0,
         fidelity: str = "auto", time_budget: float | None = None,
         progress: Progress | None = None, should_cancel: Callable[[], bool] | None = None,
         container_size: float | None = None, type_scale: float = 1.0,
         names: Sequence[str] | None = None, options: PackOptions | None = None,
         use_cache: bool = True, snapshot: Snapshot | None = None,
         attempts: int | None = None, client: object | None = None) -> Packing:
    """Pack object types into a container; returns a certified packing.

    container: mesh file path, "box:AxBxC" (a box centred at the origin) or MeshData.
    types: mesh file paths or MeshData, one per object type; shares: target shares by count
    (normalised; default uniform). container_size: scale the container so its largest
    bounding-box extent is this (container units, e.g. mm); type_scale multiplies the object
    files' coordinates. clearance: minimum gap between objects and to the wall (container
    units). time_budget (s) bounds placement (phases 1 and 2, after loading, approximation
    and numba's compilation); time an attempt leaves goes to new attempts, and the densest
    is kept; certification runs after it. progress(fraction, message) and should_cancel()
    are polled; cancel or the budget returns the best certified packing so far. A message
    starting with NOTE_PREFIX is advice to keep in view (e.g. a large scene without a
    budget), not a stage. snapshot(positions, radii, types), when given, receives the
    objects placed so far during placement, at most four times a second, from the calling
    thread: (N, 3) centres, (N,) bounding radii at their current scale, (N,) type indices
    (copies; container frame, container units), e.g. for a live view. options: the method's options
    (`core/options.py`). attempts: run exactly this many attempts (each its own random
    stream from the seed and its index) and keep the densest, ties to the earliest
    (`options.attempts.count`). client: a `distributed.Client` or a scheduler address; the
    attempts then run side by side on its workers, with the same result as one after
    another when there is no time budget (with one, each attempt stops at the deadline;
    default count: the cluster's worker threads; no snapshots). Raises
    JampackedError subclasses on bad input.
    """
    t_start = time.perf_counter()
    options = _with_attempts(options or PackOptions(), attempts)
    inputs = PackInputs(clearance=clearance, time_budget=time_budget,
                        container_size=container_size, type_scale=type_scale,
                        fidelity=fidelity, options=options)
    seed = _check_arguments(inputs, seed, types, names)
    q = _normalise_shares(shares, len(types))
    report = progress or (lambda f, m: None)

    report(0.0, "loading meshes")
    scene = _load_scene(container, types, container_size)
    t_load = time.perf_counter()

    approx = _approximate(scene, q, inputs, names, use_cache)
    expected = 0.64 * scene.volume / float(np.sum(q * approx.volumes))
    if inputs.time_budget is None and expected > LONG_WITHOUT_BUDGET:
        report(0.02, f"{NOTE_PREFIX}about {expected:,.0f} objects and no time budget: the "
               "cavity passes run until no hole is left, which takes an hour or more at this "
               "size (their time grows faster than the count). Ctrl-C stops them and keeps "
               "the best certified packing so far; --time-budget / time_budget sets a limit.")
    report(0.02, f"approximating {len(types)} object types ({approx.fidelity.name} fidelity)")
    approx.build_types(scene, q, inputs, names, use_cache)
    t_approx = time.perf_counter()

    stop = Stop(None, should_cancel)
    with contextlib.ExitStack() as stack:
        if client is not None:
            client = stack.enter_context(client_for(client))
            if inputs.options.attempts.count is None:
                inputs = replace(inputs, options=_with_attempts(
                    inputs.options, cluster_threads(client)))
        run = _place(scene, approx, q, seed, inputs, stop, report, t_approx, snapshot,
                     client)
    t_place = time.perf_counter()

    report(0.9, "certifying on the real meshes")
    run, cert, repair = _certify_ranked(run, approx, inputs, stop, report, scene.volume)
    t_cert = time.perf_counter()

    timings = {"load": t_load - t_start, "approximate": t_approx - t_load,
               "compile": run.t_compile - t_approx, **run.best.timings}
    if len(run.attempts) > 1:  # the phase times are the kept attempt's
        timings["other_attempts"] = (t_place - run.t_compile
                                     - sum(run.best.timings.values()))
    timings.update({"certify": t_cert - t_place, "total": t_cert - t_start})
    packing = _assemble(container, scene, approx, run, q, seed, inputs, stop, cert, repair,
                        timings)
    report(1.0, f"done: {packing.n} objects, density {packing.metrics['density']:.1%}")
    return packing


def _with_attempts(options: PackOptions, attempts: object) -> PackOptions:
    """`options` with a fixed count of attempts, when one is given (checked)."""
    if attempts is None:
        attempts = options.attempts.count
        if attempts is None:
            return options
    if isinstance(attempts, bool) or not isinstance(attempts, numbers.Integral) \
            or attempts < 1:
        raise InputError(f"attempts must be a whole number >= 1, got {attempts!r}.")
    return replace(options, attempts=replace(options.attempts, count=int(attempts)))


def _check_arguments(inputs: PackInputs, seed: object, types: object,
                     names: Sequence[str] | None) -> int:
    """Refuse bad arguments before any work; returns the seed as an int."""
    if isinstance(types, str | os.PathLike | MeshData) or not isinstance(
            types, Sequence | np.ndarray):
        raise InputError(f"types must be a list of object meshes (files or MeshData), one "
                         f"per object type; got {types!r}: e.g. pack(container, [{types!r}]).")
    n_types = len(types)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise InputError(f"seed must be a whole number >= 0, got {seed!r}.")
    clearance, budget = inputs.clearance, inputs.time_budget
    if not _is_real(clearance) or clearance < 0 or not math.isfinite(clearance):
        raise InputError(f"clearance must be >= 0 (container units), got {clearance!r}.")
    if not _is_real(inputs.type_scale) or not math.isfinite(inputs.type_scale) \
            or inputs.type_scale <= 0:
        raise InputError(f"type scale must be > 0, got {inputs.type_scale!r}.")
    if budget is not None and (not _is_real(budget) or not budget >= 0
                               or math.isnan(budget)):
        raise InputError(f"time_budget must be a number of seconds >= 0 or None, got "
                         f"{budget!r}.")
    if inputs.fidelity not in ("auto", *PRESETS):
        raise InputError(f"fidelity must be auto, low, medium or high, got "
                         f"{inputs.fidelity!r}.")
    size = inputs.container_size
    if size is not None and (not _is_real(size) or not math.isfinite(size) or size <= 0):
        raise InputError(f"container size must be > 0, got {size!r}.")
    if names is not None:
        if len(names) != n_types:
            raise InputError(f"{len(names)} names given for {n_types} object types.")
        bad = [n for n in names if not isinstance(n, str)]
        if bad:
            raise InputError(f"names must be strings, one per object type; got {bad[0]!r}.")
    return int(seed)


def _is_real(x: object) -> bool:
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


@dataclass
class _Scene:
    """The meshes as loaded, and the container in the container frame."""

    container: MeshData
    label: str  # the container for messages: its file or box spec
    frame_from_file: np.ndarray  # (4, 4) container frame from the container file
    vertices: np.ndarray  # (V, 3) container vertices, container frame
    volume: float  # container volume, container units^3
    types: list[MeshData]


def _load_scene(container: MeshSource, types: Sequence[MeshSource],
                container_size: float | None) -> _Scene:
    """Load the meshes; scale the container to `container_size` when given."""
    cmesh = _load(container, "container")
    frame_from_file = np.eye(4)
    if container_size is not None:
        frame_from_file[:3, :3] *= container_size / float(cmesh.extents.max())
    s_c = frame_from_file[0, 0]
    meshes = [_load(t, "object") for t in types]
    label = cmesh.path or (
        (f"'{cmesh.name}'" if cmesh.name else "(given as a mesh)")
        if isinstance(container, MeshData) else os.fspath(container))
    with np.errstate(over="ignore", under="ignore"):  # check_sizes refuses what overflowed
        return _Scene(cmesh, label, frame_from_file, cmesh.vertices * s_c,
                      cmesh.volume * s_c ** 3, meshes)


def _type_names(scene: _Scene, names: Sequence[str] | None) -> list[str]:
    """`names`, or each type's file name without its extension (a mesh given as arrays: its
    name, or "type<i>"),
    a name that repeats an earlier one followed by "-2", "-3"...: types from a/fruit.obj and
    b/fruit.obj must be told apart in the summary, the packing file and the exports."""
    if names is not None:
        return list(names)
    return distinct_names([Path(m.path).stem if m.path else (m.name or f"type{i}")
                           for i, m in enumerate(scene.types)])


def _type_sizes(scene: _Scene, type_scale: float, names: Sequence[str] | None
                ) -> list[TypeSize]:
    """The object types' names, files, extents and volumes after the type scale."""
    named = _type_names(scene, names)
    with np.errstate(over="ignore", under="ignore"):
        return [TypeSize(name=named[i],
                         path=m.path, extents=m.extents * type_scale,
                         volume=float(m.volume) * type_scale ** 3 if type_scale < 1e100
                         else math.inf)
                for i, m in enumerate(scene.types)]


def _check_request(scene: _Scene, q: np.ndarray, inputs: PackInputs,
                   names: Sequence[str] | None) -> list[TypeSize]:
    """Refuse sizes out of range and requests beyond the machine before any grid or
    lattice is allocated; returns the types' sizes."""
    sizes = _type_sizes(scene, inputs.type_scale, names)
    c_ext = np.ptp(scene.vertices, axis=0)
    check_sizes(scene.label, c_ext, scene.volume, sizes, inputs.type_scale,
                inputs.container_size)
    volumes = np.array([t.volume for t in sizes])
    cells = inputs.options.fidelity.container_cells or (
        PRESETS["high"] if inputs.fidelity == "auto" else PRESETS[inputs.fidelity]
    ).container_cells
    ph, cav = inputs.options.phases, inputs.options.cavity
    cost = estimate_cost(c_ext, scene.volume, volumes, q, cells, ph.phase1_density,
                         ph.phase2_spacing, cav.factors)
    live = [t for t, share in zip(sizes, q, strict=True) if share > 0]
    check_cost(cost, scene.label, c_ext, min(live, key=lambda t: t.volume))
    return sizes


@dataclass
class _Approximation:
    """The container grid, the fidelity chosen and the object types' approximations."""

    container: Container
    fidelity: Fidelity
    f_min: float  # the smallest type's equivalent radius, container units
    volumes: np.ndarray  # (T,) type volumes, container units^3
    types: list[ObjectType]

    def build_types(self, scene: _Scene, q: np.ndarray, inputs: PackInputs,
                    names: Sequence[str] | None, use_cache: bool) -> None:
        """Approximate every object type; refuse a type no interior point can hold."""
        named = _type_names(scene, names)
        for i, m in enumerate(scene.types):
            name = named[i]
            self.types.append(build_type(
                name, m.vertices, m.faces, path=m.path, sha256=m.sha256, share=float(q[i]),
                type_scale=inputs.type_scale, fidelity=self.fidelity, use_cache=use_cache,
                reach=inputs.clearance))
        check_types_fit(self.types, self.container, inputs.clearance)


def _approximate(scene: _Scene, q: np.ndarray, inputs: PackInputs,
                 names: Sequence[str] | None, use_cache: bool) -> _Approximation:
    """The container grid and the fidelity: the container's depth decides the automatic
    fidelity, which decides the container grid, so the grid is built at medium's (or the
    preset's) resolution and again only if that changes."""
    clearance, type_scale = inputs.clearance, inputs.type_scale
    sizes = _check_request(scene, q, inputs, names)
    volumes = np.array([t.volume for t in sizes])
    expected = 0.5 * scene.volume / float(np.sum(q * volumes))
    f_min = float(equivalent_radius(volumes.min()))
    fid = PRESETS["medium"] if inputs.fidelity == "auto" else preset(inputs.fidelity,
                                                                     clearance)
    cmesh = scene.container
    # grids alone until the spacing is chosen: the solver's arrays beside the grid
    # (`container_on`) cost as much again on a thin tray's fine grids
    grid = container_grid(scene.vertices, cmesh.faces, f_min / fid.container_cells)
    depth = float(grid.values.max())
    live = [i for i, share in enumerate(q) if share > 0]
    measured = None  # (depth, grid) on a grid fine across the container, once measured
    # an object's inscribed radius is at most half its thinnest extent: below that depth
    # some type may not fit, and its inner room (a lower bound of that radius) decides
    if depth < min(float(sizes[i].extents.min()) for i in live) / 2 + clearance:
        live_sizes = [replace(sizes[i], room=inner_room(scene.types[i].vertices,
                                                          scene.types[i].faces) * type_scale)
                      for i in live]
        if depth < min(t.room for t in live_sizes) + clearance:  # measured again, finer
            measured = measured_depth(scene.vertices, cmesh.faces, grid)
            depth, spacing = measured[0], measured[1].spacing
            # the grid's depth is within a cell of the true depth
            if depth + spacing < min(t.room for t in live_sizes) + clearance:
                refuse_no_room(scene.label, scene.vertices, live_sizes, depth, spacing,
                               clearance)
    # a thin-walled or slender type can have the depth it needs and still be too long
    refuse_too_long(scene.label, scene.vertices, sizes, q, clearance)
    if inputs.fidelity == "auto":
        local = [(m.vertices - m.vertices.mean(axis=0)) * type_scale for m in scene.types]
        r_max = max(float(np.sqrt((v ** 2).sum(axis=1)).max()) for v in local)
        fid = choose_fidelity(local, expected, clearance, depth / f_min, depth / r_max)
    fid = _with_overrides(fid, inputs.options.fidelity)
    spacing = f_min / fid.container_cells
    if inputs.options.fidelity.container_cells is None:
        fine, measured = tight_fit_spacing(scene.vertices, cmesh.faces, scene.types, sizes,
                                           live, grid, depth, spacing, clearance,
                                           type_scale, measured)
        if fine < spacing:
            # the grid's cap on cells per axis may keep it coarser than asked: then a thin
            # tray's depth was measured on that same grid already
            same = (measured is not None
                    and measured[1].spacing == grid_spacing(scene.vertices, fine))
            grid = measured[1] if same else container_grid(scene.vertices, cmesh.faces, fine)
            spacing = grid.spacing
            cells = f_min / spacing
            capped = " (the most the container's size allows)" if spacing > fine else ""
            fid = replace(fid, container_cells=cells, reasons=fid.reasons + (
                f"an object only just fits: {cells:.3g} container grid cells per "
                f"radius{capped}",))
    if grid.spacing != spacing:
        grid = container_grid(scene.vertices, cmesh.faces, spacing)
    cont = container_on(scene.vertices, cmesh.faces, scene.volume, grid)
    return _Approximation(cont, fid, f_min, volumes, [])


#: objects a packing without a time budget may hold before the run says it will take long
#: (without one, 1,141 objects took 20 minutes on 2 cores: docs/benchmarks.md, "Growth")
LONG_WITHOUT_BUDGET = 2500


@dataclass
class _Placed:
    """The placement stage's outcome: the densest attempts and what they took."""

    #: the kept attempt: the densest, until certification keeps a denser certified one
    best: Attempt
    ranked: list[Attempt]  # densest first (`placement.ranked_with`)
    attempts: list[AttemptSummary]
    margins: Margins
    tuner: ThreadTuner | None
    phase1_spacing: float
    t_compile: float  # when the kernels were ready (perf_counter)
    #: (T,) the shares the attempts packed for: the asked ones, less the types left out
    packed: np.ndarray
    left_out: list[OutOfReach]

    def shares_of(self, att: Attempt) -> np.ndarray:
        """The shares `att` packed for: `packed` less the types it gave up."""
        return shares_without(self.packed, att.given_up)


def _place(scene: _Scene, approx: _Approximation, q: np.ndarray, seed: int,
           inputs: PackInputs, stop: Stop, report: Progress, t_approx: float,
           snapshot: Snapshot | None = None, client: object | None = None) -> _Placed:
    """Margins, solver and kernels ready, then the attempts of the placement; the time
    budget starts once the kernels are compiled."""
    opts, clearance = inputs.options, inputs.clearance
    cont, objtypes = approx.container, approx.types
    table = TypeTable(objtypes)
    mo = opts.margins
    margins = contact_margins(objtypes, cont.grid, cont.vertices, cont.faces, mo.safety,
                              mo.safety_sharp, mo.wall_safety, mo.wall_safety_sharp, clearance)
    # a type no point of the container can hold with its margins: the others pack without it
    left_out = out_of_reach(objtypes, cont, margins, clearance)
    if left_out:
        q = q.copy()
        q[[o.type for o in left_out]] = 0.0
        q = q / q.sum()
    ph = opts.physics
    solver_params = SolverParams(
        clearance=clearance, tol=1e-6 * approx.f_min, k_obj=ph.k_obj, k_wall=ph.k_wall,
        k_rot=ph.k_rot, damping=ph.damping, wall_margin=margins.wall)
    if cache_is_cold():  # say why the wait before the budget: numba compiles (seconds)
        report(0.03, COMPILE_MESSAGE)
    Solver(cont, table, PackState(), solver_params).warm_up()
    tuner = ThreadTuner(numba.get_num_threads()) if opts.tune_threads else None
    t_compile = time.perf_counter()
    if inputs.time_budget is not None:
        stop.deadline = time.perf_counter() + float(inputs.time_budget)
    s1 = (float(np.sum(q * approx.volumes)) / opts.phases.phase1_density) ** (1 / 3)

    def new_solver() -> Solver:
        return Solver(cont, table, PackState(), solver_params, tuner)

    if client is not None:  # the attempts side by side on the cluster's workers
        job = AttemptJob(cont, objtypes, solver_params, q, s1, approx.f_min, seed,
                         margins.objects, opts, scene.volume)
        ranked, attempts = place_on_cluster(client, job, opts.attempts.count, new_solver,
                                            stop, report)
    else:
        ranked, attempts = place(new_solver, q, s1, approx.f_min, seed, stop,
                                 margins.objects, opts, scene.volume, report,
                                 None if snapshot is None else Snapshots(snapshot,
                                                                         table.radius))
    return _Placed(ranked[0], ranked, attempts, margins, tuner, s1, t_compile, q, left_out)


def _certify_ranked(run: _Placed, approx: _Approximation, inputs: PackInputs, stop: Stop,
                    report: Progress, c_volume: float) -> tuple[_Placed, dict, RepairStats]:
    """Certify the densest attempt and, while a runner-up was denser before certification
    than the densest certified so far (its repair removed objects), that one too; returns
    the run keeping the densest certified attempt (ties: the one ranked first), with its
    certificate and repair. Each certified attempt's summary records its density after
    certification, the kept one's says so. A cancel certifies only the first."""
    kept: tuple[Attempt, dict, RepairStats, float] | None = None
    objtypes = approx.types
    # one certifier (and its worker processes) for every attempt: the meshes are the same
    with Certifier(approx.container, [t.vertices for t in objtypes],
                   [t.faces for t in objtypes], run.best.solver.t.volume,
                   np.array([t.max_edge for t in objtypes]),
                   processes=inputs.options.repair.processes) as certifier:
        for k, att in enumerate(run.ranked):
            if kept is not None and (att.density <= kept[3] or (
                    stop.should_cancel is not None and stop.should_cancel())):
                break
            if k == 0:
                def progress(f: float, m: str) -> None:
                    report(0.9 + 0.09 * f, m)
            else:
                said = (f"attempt {att.index + 1}, denser than attempt {kept[0].index + 1} "
                        "after its repair: ")

                def progress(f: float, m: str, said: str = said) -> None:
                    report(0.99, said + m)
            shares = run.shares_of(att)
            cert, repair = _certify(att.solver, certifier, shares, inputs.clearance,
                                    inputs.options, stop, progress)
            density = snapshot_metrics(att.solver.s, att.solver.t.volume, shares,
                                       c_volume)["density"]
            run.attempts[att.index].certified = density
            if kept is None or density > kept[3]:
                kept = (att, cert, repair, density)
    assert kept is not None
    att, cert, repair, _ = kept
    run.attempts[att.index].kept = True
    return replace(run, best=att), cert, repair


def _certify(solver: Solver, certifier: Certifier, q: np.ndarray, clearance: float,
             options: PackOptions, stop: Stop,
             progress: Callable[[float, str], None]) -> tuple[dict, RepairStats]:
    """Certify on the real meshes and repair (never skipped, also after cancel); objects
    not grown to full size are dropped first. q: (T,) target shares, summing to 1;
    progress(fraction of a check, message)."""
    state = solver.s
    state.alive[: state.n] &= (state.scale[: state.n] >= 1.0).astype(np.uint8)
    return certify_and_repair(
        solver, certifier, clearance, options.repair,
        lambda: bool(stop.should_cancel is not None and stop.should_cancel()),
        timed=stop.deadline is not None, shares=q, max_tvd=options.cavity.max_tvd,
        progress=progress)


def _assemble(container: MeshSource, scene: _Scene, approx: _Approximation, run: _Placed,
              q: np.ndarray, seed: int, inputs: PackInputs, stop: Stop, cert: dict,
              repair: RepairStats, timings: dict) -> Packing:
    """The Packing of the certified objects, with its metrics and run report."""
    state = run.best.solver.s
    objtypes = approx.types
    idx = state.alive_indices()
    clearance = inputs.clearance
    if len(idx) == 0 and not stop.reason:
        depth = measured_depth(scene.vertices, scene.container.faces,
                               approx.container.grid)[0]  # the grid's nodes can miss it
        raise PackingError(nothing_placed_message(depth, objtypes, run.margins,
                                                  approx.container, scene.vertices, clearance,
                                                  approx.fidelity.name))
    typ = state.typ[idx].copy()
    pos = state.pos[idx].copy()
    quat = matrix_to_quat(quat_to_matrix(state.quat[idx]))  # canonical sign, unit length
    metrics = compute_metrics(typ, pos, run.best.solver.t.volume, q, scene.volume)
    metrics.update(run.best.after)
    report = RunReport(
        fidelity=approx.fidelity.name, fidelity_detail=approx.fidelity,
        stopped=stop.reason or None,
        container_grid_spacing=approx.container.grid.spacing,
        phase1_spacing=run.phase1_spacing,
        spheres_per_type=[int(len(t.sphere_radii)) for t in objtypes],
        surface_points_per_type=[int(len(t.surface_points)) for t in objtypes],
        sphere_coverage_per_type=[
            sphere_coverage(t.grid, t.sphere_centres, t.sphere_radii) for t in objtypes],
        phase1=run.best.phase1, phase2=run.best.phase2,
        extra_passes=run.best.extra_passes, attempts=run.attempts,
        margins=run.margins.report(), repair=repair,
        threads=None if run.tuner is None else run.tuner.report(),
        given_up=list(run.best.given_up),
        warnings=[w for m in [scene.container, *scene.types] for w in m.warnings]
        + run_warnings([t.name for t in objtypes], q, np.bincount(typ, minlength=len(q)),
                       float(metrics["tvd"]), inputs.options.cavity.max_tvd,
                       run.best.phase1, inputs.time_budget, stop.reason or None,
                       inputs.options.attempts.count, len(run.attempts),
                       extra_passes_ran=bool(run.best.extra_passes),
                       passes_seconds=run.best.timings["phase2"] + run.best.timings["extra"],
                       left_out=[(o.type, o.need, o.has, o.why) for o in run.left_out],
                       given_up=run.best.given_up,
                       mix_held=run.best.mix_held,
                       clearance=clearance, fidelity=approx.fidelity.name)
        + slow_certification(timings["certify"], inputs.time_budget,
                             [t.name for t in objtypes],
                             [len(t.faces) if np.any(typ == i) else 0
                              for i, t in enumerate(objtypes)]))
    packing = Packing(
        container_path=_source_name(container, scene.container),
        container_sha256=scene.container.sha256, frame_from_file=scene.frame_from_file,
        container_volume=scene.volume,
        types=[TypeRecord(name=t.name, path=t.path, sha256=t.sha256, share=t.share,
                          local_from_file=t.local_from_file, volume=t.volume)
               for t in objtypes],
        type_index=typ, rotations=quat, translations=pos, scales=np.ones(len(idx)),
        inputs=inputs, report=report, seed=seed, metrics=metrics, timings=timings,
        certificate=cert)
    record_digest(packing)  # what the certificate vouches for, to tell edits apart
    return packing


def _with_overrides(fid: Fidelity, overrides: FidelityOverrides) -> Fidelity:
    """The fidelity with the options' explicit overrides applied (benchmarks sweep these)."""
    over = overrides.given()
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
