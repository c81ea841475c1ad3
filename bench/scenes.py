"""Benchmark scenes and the one-run record every benchmark writes.

Each run is its own process (`run_in_child`), so numba's and the approximation cache's state
is explicit: the caller passes the cache folders in the environment. A run record holds the
wall time per phase, objects per type, density, TVD, NNI, the worst exact overlap and wall
violation before certification, and how many objects certification moved or removed.
Meshes come from ../shared/meshes beside the checkout (or --meshes DIR).
"""

from __future__ import annotations

import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import uuid
from dataclasses import asdict
from pathlib import Path

import numpy as np

_DENSITY = re.compile(r"density ([0-9.]+)%")
ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
MESHES = ROOT.parent / "shared" / "meshes"

POLY = [f"polyhedra/convex5/polytope{i}.obj" for i in range(1, 6)]
NONCONVEX = [f"polyhedra/nonconvex10/polytope{i}.obj" for i in range(1, 11)]
FRUIT = [f"fruit/ycb_lowpoly/{n}.obj" for n in
         ("011_banana", "012_strawberry", "014_lemon", "015_peach", "017_orange")]
#: the same five fruit as full YCB scans (16,000 faces each), as issue 19 tried them
FRUIT_SCANS = [f"fruit/ycb/{n}.ply" for n in
               ("011_banana", "012_strawberry", "014_lemon", "015_peach", "017_orange")]
ARMADILLO = {"container_size": 200.0, "type_scale": 250.0}
#: boxy types a maker stacks (plates, bricks, tiles), kept beside the bench: an absolute
#: path stays itself when joined to the meshes folder
BOXY = ROOT / "bench" / "meshes"

#: name -> container, types, pack() keyword arguments, bars, what the numbers compare with.
#: Budgets bound placement (pack's time_budget); loading, compiling and certifying come on top.
SCENES: dict[str, dict] = {
    "polyhedra-80": {
        "container": "box:43.4338x41.8435x45.0059", "types": POLY,
        "kwargs": {"time_budget": 55.0},
        "bars": {"density": 0.50, "seconds": 60.0},
        "reference": "Romanova et al. 2018: 80 objects (60.6%); paper (Table 2): 78 objects, "
                     "45.5%, 139 s on 12 cores",
        "paper": {"objects": 78, "density": 0.455, "seconds": 139.0},
    },
    "fruit-in-bunny": {
        "container": "containers/bunny.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 170.0},
        "bars": {"density": 0.55, "tvd": 0.05, "nni": 1.1, "seconds": 180.0},
        "reference": "issue 5 bar: >= 55% certified, TVD <= 0.05, NNI >= 1.1, <= 3 min",
    },
    "fruit-in-bunny-5min": {
        "container": "containers/bunny.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 265.0},
        "bars": {"density": 0.50, "tvd": 0.1, "nni": 1.0, "seconds": 300.0},
        "reference": "issue 2 bar: >= 50% certified, TVD <= 0.1, NNI >= 1.0, <= 5 min",
    },
    "fruit-in-torus": {
        "container": "containers/torus.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 90.0},
        "reference": "genus 1: 200 mm torus, 40 mm tube; five fruit x300",
    },
    "fruit-in-knight": {
        "container": "containers/knight.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 120.0},
        "reference": "thin features (ears, mane): 200 mm knight; five fruit x300",
    },
    "nonconvex10-box": {
        "container": "box:35x30x40", "types": NONCONVEX,
        "kwargs": {"time_budget": 60.0},
        "reference": "the ten non-convex polyhedra of Stoyan et al. 2004 (ESICUP Examples "
                     "2-5 use a 35 x 30 base), uniform shares; 5 of each would fill 48%",
    },
    # issue 19: a thin container, and a printing clearance. A scene with a "clearance"
    # names the scene without it ("without"); its row gives the clearance's physical cost
    # (each type dilated by half the clearance, `core/dilation.py`) beside the density lost
    "armadillo-ycb": {
        "container": "containers/armadillo.obj", "types": FRUIT_SCANS,
        "kwargs": {**ARMADILLO, "time_budget": 120.0},
        "reference": "issue 19: 200 mm Armadillo, five YCB scans x250, equal shares; 49.2% "
                     "with 120 s (the paper's Armadillo scene: 54%)",
    },
    "armadillo-ycb-c0.2": {
        "container": "containers/armadillo.obj", "types": FRUIT_SCANS,
        "kwargs": {**ARMADILLO, "time_budget": 120.0, "clearance": 0.2},
        "without": "armadillo-ycb",
        "reference": "issue 19: armadillo-ycb with a 0.2 mm clearance (44.0% with 240 s)",
    },
    "fruit-in-bunny-c0.5": {
        "container": "containers/bunny.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 170.0,
                   "clearance": 0.5},
        "without": "fruit-in-bunny",
        "reference": "issue 19: fruit-in-bunny with a 0.5 mm clearance",
    },
    "polyhedra-80-c0.5": {
        "container": "box:43.4338x41.8435x45.0059", "types": POLY,
        "kwargs": {"time_budget": 55.0, "clearance": 0.5},
        "without": "polyhedra-80",
        "reference": "polyhedra-80 with a 0.5 mm clearance: low-poly objects with large "
                     "flat faces",
    },
    # boxy types, where rows of them fill a box (`core/stacking.py`); the boxes are not
    # multiples of the types, as a maker's crate rarely is
    "plates-in-box": {
        "container": "box:31x31x30", "types": [str(BOXY / "plate_10x10x0.5.stl")],
        "kwargs": {"time_budget": 40.0},
        "reference": "10 x 10 x 0.5 mm plates; a stack of 3 x 3 x 57 holds 89%",
    },
    "bricks-in-crate": {
        "container": "box:103x62x52", "types": [str(BOXY / "brick_20x10x5.stl")],
        "kwargs": {"time_budget": 60.0},
        "reference": "20 x 10 x 5 mm bricks; a stack of 5 x 6 x 10 holds 90%",
    },
    "two-bricks": {
        "container": "box:103x62x52",
        "types": [str(BOXY / "brick_20x10x5.stl"), str(BOXY / "brick_10x10x5.stl")],
        "kwargs": {"time_budget": 60.0},
        "reference": "20 x 10 x 5 and 10 x 10 x 5 mm bricks, equal shares: rows of both in "
                     "turn",
    },
    "bricks-two-colours": {
        "container": "box:100x60x50",
        "types": [str(BOXY / "brick_20x10x5.stl"), str(BOXY / "brick_20x10x5.stl")],
        "kwargs": {"time_budget": 60.0},
        "reference": "one 20 x 10 x 5 mm brick as two types (two colours), equal shares, in "
                     "a box sized for 5 x 6 x 10 of it: 300 hold 100%",
    },
    "two-tiles": {
        "container": "box:42x40x30",
        "types": [str(BOXY / "tile_12x8x1.stl"), str(BOXY / "tile_9x6x1.stl")],
        "kwargs": {"time_budget": 40.0},
        "reference": "12 x 8 x 1 and 9 x 6 x 1 mm tiles, equal shares",
    },
    "coins-in-jar": {
        "container": str(BOXY / "jar_80x60.stl"), "types": [str(BOXY / "coin_25x2.stl")],
        "kwargs": {"time_budget": 30.0},
        "reference": "25 x 2 mm coins in a jar 80 mm across and 60 high: seven staggered "
                     "columns",
    },
    "cans-in-box": {
        "container": "box:61x61x40", "types": [str(BOXY / "can_6x10.stl")],
        "kwargs": {"time_budget": 30.0},
        "reference": "cans 6 mm across and 10 high standing staggered",
    },
    "large-2000": {
        "container": "containers/bunny.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 140.0, "time_budget": 420.0},
        "reference": "five fruit x140 in the 200 mm bunny: about 2000 objects",
    },
}


def physical_cost(types: list[str], type_scale: float, clearance: float,
                  shares: list[float] | None = None, meshes: Path = MESHES) -> dict:
    """The clearance's physical cost for a scene's types (files under `meshes`, scaled by
    type_scale, count shares equal unless given): `core.dilation.clearance_cost`."""
    from jampacked.core.dilation import clearance_cost
    from jampacked.core.meshes import load_mesh

    loaded = [load_mesh(meshes / t) for t in types]
    parts = [(np.asarray(m.vertices, np.float64) * type_scale, np.asarray(m.faces, np.int64))
             for m in loaded]
    return clearance_cost(parts, shares or [1.0] * len(types), clearance)


def clearance_row(clearance: float, cost: float, density: float,
                  density_without: float | None) -> dict:
    """A clearance scene's comparison with its scene without: the density the physical
    cost allows (issue 19's bar: without x (1 - cost) - 1 point) and what was lost."""
    row = {"clearance": clearance, "physical_cost": cost, "density": density,
           "density_without": density_without, "density_lost": None, "target": None,
           "meets_target": None}
    if density_without:
        row["density_lost"] = 1.0 - density / density_without
        row["target"] = density_without * (1.0 - cost) - 0.01
        row["meets_target"] = bool(density >= row["target"])
    return row


def median_phase_seconds(runs: list[dict]) -> dict[str, float]:
    """Median seconds of each phase over run records; a phase some runs lack (other_attempts
    when a run made one attempt) took them 0 s."""
    names = dict.fromkeys(k for r in runs for k in r["timings"])
    return {k: statistics.median([r["timings"].get(k, 0.0) for r in runs]) for k in names}


def run_record(container: str, types: list[str], seed: int, kwargs: dict,
               params: dict | None = None, meshes: Path = MESHES) -> dict:
    """Pack one scene in this process and return its record (see the module doc)."""
    from jampacked.core.api import pack
    from jampacked.core.options import PackOptions

    if not container.startswith("box:"):
        container = str(meshes / container)
    type_paths = [str(meshes / t) for t in types]
    options = PackOptions.from_flat(params or {})
    trace: list[tuple[float, float]] = []

    def progress(fraction: float, message: str) -> None:
        # the phases report "density 41.2%" (full-size objects, before certification)
        m = _DENSITY.search(message)
        if m:
            trace.append((time.perf_counter() - t0, float(m.group(1)) / 100))

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    worker_cpu0 = before.ru_utime + before.ru_stime
    t0 = time.perf_counter()
    c0 = time.process_time()
    p = pack(container, type_paths, seed=seed, options=options, progress=progress, **kwargs)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - c0
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    rep, run = asdict(p.report.repair), p.report
    return {
        "seed": seed, "wall_seconds": wall, "timings": p.timings,
        # every thread's CPU time: on a busy machine it follows the work more closely
        "cpu_seconds": cpu,
        "metrics": dict(p.metrics),
        "count_per_type": dict(zip([t.name for t in p.types],
                                   p.metrics["count_per_type"], strict=True)),
        "certificate": p.certificate,
        "before_certification": rep["first"],
        "repair": {k: v for k, v in rep.items() if k != "first"},
        "fidelity": run.fidelity, "fidelity_detail": asdict(run.fidelity_detail),
        "spheres_per_type": run.spheres_per_type,
        "container_grid_spacing": run.container_grid_spacing,
        "phase1": asdict(run.phase1), "phase2": asdict(run.phase2),
        "attempts": [asdict(a) for a in run.attempts],
        "stopped": run.stopped, "kwargs": kwargs, "params": params or {},
        "threads": None if run.threads is None else asdict(run.threads),
        "density_trace": trace,
        # the process's peak resident memory so far (Linux reports KiB), MiB
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        # certification's worker processes' CPU time together, s (`core/check_pool.py`;
        # not their memory: a spawned child's ru_maxrss starts at its parent's)
        "worker_cpu_seconds": children.ru_utime + children.ru_stime - worker_cpu0,
    }


def run_in_child(container: str, types: list[str], seed: int, kwargs: dict,
                 params: dict | None = None, *, env: dict | None = None,
                 meshes: Path = MESHES) -> dict:
    """`run_record` in a fresh Python process (own numba state); returns its record."""
    job = {"container": container, "types": types, "seed": seed, "kwargs": kwargs,
           "params": params, "meshes": str(meshes), "parent": os.getpid()}
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out = Path(f.name)
    try:
        subprocess.run([sys.executable, __file__, json.dumps(job), str(out)], check=True,
                       env=env)
        return json.loads(out.read_text())
    finally:
        out.unlink(missing_ok=True)


class Runs:
    """Where a sweep's runs go, each `run_in_child` (a fresh process, own numba state and
    timings): one after another here (no client: `start` runs it at once), or side by side on
    a Dask cluster's workers (`start` submits a task that starts the child process on a
    worker; `record` waits for it). Dask re-runs a lost worker's task elsewhere and a future
    gives one result, so no run is lost or doubled; the caller writes every result.

    Each record gets "cluster": None one after another, else the scheduler's address, its
    worker processes and threads (runs side by side) when the sweep started, and the worker
    that ran it. On a remote cluster the checkout and the meshes must be at the same paths."""

    def __init__(self, client=None):
        self.client = client
        self.cluster = None
        if client is not None:
            import cloudpickle

            # bench/ is no package the workers can import: send this module's code along
            cloudpickle.register_pickle_by_value(sys.modules[__name__])
            threads = client.nthreads()
            self.cluster = {"scheduler": client.scheduler.address, "workers": len(threads),
                            "threads": sum(threads.values())}

    def start(self, container: str, types: list[str], seed: int, kwargs: dict,
              params: dict | None = None, *, env: dict, meshes: Path = MESHES):
        """One run: its record (one after another) or its future (on the cluster)."""
        if self.client is None:
            return {**run_in_child(container, types, seed, kwargs, params, env=env,
                                   meshes=meshes), "cluster": None}
        # only what this sweep sets (the caches' folders); the rest is the worker's own
        changed = {k: v for k, v in env.items() if os.environ.get(k) != v}
        return self.client.submit(_run_on_worker, container, types, seed, kwargs, params,
                                  changed, str(meshes), pure=False,
                                  key=f"bench-run-{seed}-{uuid.uuid4().hex}")

    def record(self, started) -> dict:
        """The record of a run `start` returned."""
        if self.client is None:
            return started
        rec = started.result()
        started.release()
        return {**rec, "cluster": {**self.cluster, **rec["cluster"]}}


def _run_on_worker(container: str, types: list[str], seed: int, kwargs: dict,
                   params: dict | None, env: dict, meshes: str) -> dict:
    """A Dask task: `run_in_child` on this worker, with `env` over the worker's environment."""
    from distributed import get_worker

    rec = run_in_child(container, types, seed, kwargs, params, env=dict(os.environ, **env),
                       meshes=Path(meshes))
    return {**rec, "cluster": {"worker": get_worker().address}}


def fresh_cache_env(folder: str) -> dict:
    """Environment whose numba and approximation caches live (empty) under `folder`."""
    return dict(os.environ, NUMBA_CACHE_DIR=os.path.join(folder, "numba"),
                JAMPACKED_CACHE=os.path.join(folder, "jampacked"))


def write_text(path: Path, text: str) -> None:
    """Atomic text write (temporary file + rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_json(path: Path, data, default=None) -> None:
    """Atomic JSON write; default converts what json cannot (as in json.dumps)."""
    write_text(path, json.dumps(data, indent=1, default=default))


def save_figure(fig, path: Path) -> None:
    """Atomic PNG write of a matplotlib figure."""
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def exit_with_parent(parent: int, period: float = 0.5) -> None:
    """End this process (exit status 3) once `parent`, the process that started it, is gone
    (this one is then re-parented): a run whose sweep or Dask worker died would otherwise
    run on beside its re-run and slow it."""
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(period)
        os._exit(3)

    threading.Thread(target=watch, daemon=True, name="exit-with-parent").start()


if __name__ == "__main__":  # child process of run_in_child
    job = json.loads(sys.argv[1])
    if job.get("parent") is not None:
        exit_with_parent(job["parent"])
    rec = run_record(job["container"], job["types"], job["seed"], job["kwargs"],
                     job["params"], Path(job["meshes"]))
    Path(sys.argv[2]).write_text(json.dumps(rec))
