"""Dask: attempts of one packing on a LocalCluster against one after another, and a batch of
scenes with a worker killed midway against the same batch here.

    python bench/dask_cluster.py [--attempts 4] [--scenes 20] [--workers 2]

Attempts: the same N attempts (no budget) of one scene, one after another in this process,
then on a LocalCluster of `--workers` single-threaded worker processes (started and warmed up
before the clock starts); same densest packing? wall ratio (target <= 0.6x). Batch: `--scenes`
tiny scenes packed here one after another, then on the cluster with one worker killed
(os._exit) once it runs a scene; all present, certified, identical to the local packings?
Timings are wall-clock seconds on this shared 2-core machine: the load average is recorded
next to them. Writes bench/results/dask_cluster.json and dask_cluster.png. (Not named
distributed.py: as a script's folder is first on sys.path, that would shadow the package.)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import RESULTS, save_figure, write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
POLY = [str(ROOT / "tests" / "data" / "meshes" / "polyhedra" / "convex5" / f"polytope{i}.obj")
        for i in (1, 3)]
ATTEMPT_SCENE = "box:34x30x32"  # two dozen objects: tens of seconds per attempt here
BATCH_BOXES = ("box:22x20x21", "box:16x15x14")


def _load() -> float:
    return os.getloadavg()[0]


def _same(a, b) -> bool:
    return (np.array_equal(a.type_index, b.type_index)
            and np.array_equal(a.translations, b.translations)
            and np.array_equal(a.rotations, b.rotations))


def bench_attempts(client, n: int, reps: int) -> dict:
    from jampacked.core.api import pack

    runs = []
    for rep in range(reps):
        load0 = _load()
        t = time.perf_counter()
        here = pack(ATTEMPT_SCENE, POLY, seed=3, fidelity="low", attempts=n)
        t_here = time.perf_counter() - t
        t = time.perf_counter()
        there = pack(ATTEMPT_SCENE, POLY, seed=3, fidelity="low", attempts=n, client=client)
        t_there = time.perf_counter() - t
        runs.append({
            "rep": rep, "load_before": load0, "load_after": _load(),
            "sequential_seconds": t_here, "cluster_seconds": t_there,
            "ratio": t_there / t_here, "same_packing": _same(here, there),
            "densities": [a.density for a in here.report.attempts],
            "cluster_densities": [a.density for a in there.report.attempts],
            "count": here.n, "density": here.metrics["density"],
            "certified": bool(there.certificate["certified"]),
            "sequential_timings": here.timings, "cluster_timings": there.timings})
        print(f"attempts rep {rep}: here {t_here:.1f} s, cluster {t_there:.1f} s, ratio "
              f"{t_there / t_here:.2f}, same {runs[-1]['same_packing']}, load {load0:.1f}",
              flush=True)
    return {"scene": ATTEMPT_SCENE, "types": POLY, "seed": 3, "fidelity": "low",
            "attempts": n, "median_ratio": statistics.median(r["ratio"] for r in runs),
            "all_same": all(r["same_packing"] for r in runs), "runs": runs}


def bench_batch(client, n_scenes: int) -> dict:
    from jampacked.core.batch import check_done, run_batch, scene_file
    from jampacked.core.batch_file import SceneSpec

    scenes = [SceneSpec(id=f"b{k:02d}", container=BATCH_BOXES[k % 2], types=tuple(POLY),
                        seed=k // 2 + 1, fidelity="low") for k in range(n_scenes)]
    with tempfile.TemporaryDirectory() as here_dir, \
            tempfile.TemporaryDirectory() as there_dir:
        load0 = _load()
        t = time.perf_counter()
        local = run_batch(scenes, here_dir)
        t_here = time.perf_counter() - t
        results: list = []
        t = time.perf_counter()
        runner = threading.Thread(target=lambda: results.extend(
            run_batch(scenes, there_dir, client)))
        runner.start()
        killed, t_kill = None, None
        while killed is None and runner.is_alive():
            busy = [w for w, keys in client.processing().items() if keys]
            if busy and time.perf_counter() - t > 0.3 * t_here / 2:  # midway, roughly
                killed, t_kill = busy[0], time.perf_counter() - t
                with contextlib.suppress(Exception):
                    client.run(os._exit, 1, workers=[killed])
            time.sleep(0.05)
        runner.join()
        t_there = time.perf_counter() - t
        files = sorted(p.name for p in Path(there_dir).glob("b*.json"))
        checks = []
        for spec, mine in zip(scenes, local, strict=True):
            done, why = check_done(spec, scene_file(there_dir, spec))
            checks.append({"id": spec.id, "verified": done is not None, "why": why,
                           "certified": bool(done is not None
                                             and done.certificate["certified"]),
                           "identical": bool(done is not None and _same(done, mine.packing)),
                           "count": None if done is None else done.n})
    out = {
        "scenes": n_scenes, "boxes": BATCH_BOXES, "load_before": load0, "load_after": _load(),
        "local_seconds": t_here, "cluster_seconds": t_there, "ratio": t_there / t_here,
        "killed_worker": killed, "killed_at_seconds": t_kill,
        "statuses": [r.status for r in results], "files": len(files),
        "all_present": len(files) == n_scenes and all(c["verified"] for c in checks),
        "all_certified": all(c["certified"] for c in checks),
        "all_identical": all(c["identical"] for c in checks), "scenes_checked": checks}
    print(f"batch: here {t_here:.1f} s, cluster {t_there:.1f} s (worker killed at "
          f"{t_kill} s), present {out['all_present']}, certified {out['all_certified']}, "
          f"identical {out['all_identical']}, load {load0:.1f}", flush=True)
    return out


def chart(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a, b = data["attempts"], data["batch"]
    fig, ax = plt.subplots(figsize=(6, 3.2))
    labels = [f"{a['attempts']} attempts", f"batch of {b['scenes']}\n(worker killed)"]
    here = [statistics.median(r["sequential_seconds"] for r in a["runs"]), b["local_seconds"]]
    there = [statistics.median(r["cluster_seconds"] for r in a["runs"]), b["cluster_seconds"]]
    x = np.arange(2)
    ax.bar(x - 0.2, here, 0.4, label="one after another")
    ax.bar(x + 0.2, there, 0.4, label=f"LocalCluster, {data['workers']} workers")
    ax.set_xticks(x, labels)
    ax.set_ylabel("wall seconds")
    ax.set_title(f"Dask on this shared 2-core machine (load {a['runs'][0]['load_before']:.1f}"
                 f" and {b['load_before']:.1f})")
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--attempts", type=int, default=4)
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    import distributed

    from jampacked.core.api import pack

    pack(BATCH_BOXES[1], POLY, seed=1, fidelity="low")  # numba's cache loaded here
    t = time.perf_counter()
    with distributed.LocalCluster(n_workers=args.workers, threads_per_worker=1,
                                  processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        t_start = time.perf_counter() - t
        pack(BATCH_BOXES[1], POLY, seed=1, fidelity="low", attempts=args.workers,
             client=client)  # and on every worker
        t_warm = time.perf_counter() - t - t_start
        data = {"workers": args.workers, "cores": os.cpu_count(),
                "cluster_start_seconds": t_start, "cluster_warm_up_seconds": t_warm,
                "attempts": bench_attempts(client, args.attempts, args.reps)}
        client.wait_for_workers(args.workers, timeout=120)
        data["batch"] = bench_batch(client, args.scenes)
    RESULTS.mkdir(parents=True, exist_ok=True)
    write_json(RESULTS / "dask_cluster.json", data)
    chart(data, RESULTS / "dask_cluster.png")
    print(f"wrote {RESULTS / 'dask_cluster.json'} and dask_cluster.png")


if __name__ == "__main__":
    main()
