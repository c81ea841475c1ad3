"""Busy machine: placement time when the cores are shared, for three thread settings.

    python bench/busy_machine.py [--objects 1000] [--reps 3]

The scene is growth.py's (oranges and lemons in a cube sized for about N objects, the
paper's two phases, one attempt), so every run does the same work and ends in the same
packing whatever its thread count. Thread settings:

- tuned: the default; the solver times one thread against all of numba's and keeps the
  faster (`core/threads.py`);
- every thread: `tune_threads=False`, the contact tests always on all of numba's threads;
- one thread: `NUMBA_NUM_THREADS=1`.

Loads: idle; two busy Python loops (one per core of this 2-core machine); another packing
of the same scene with the same setting, in a loop. The placement time (phase 1 + phase 2)
is capped by the time budget (--cap); a capped run is marked. Writes
bench/results/busy_machine.json and busy_machine.png.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from growth import SIDE_60_COUNT, TYPE_SCALE, TYPES  # noqa: E402
from scenes import (  # noqa: E402
    MESHES,
    RESULTS,
    fresh_cache_env,
    run_in_child,
    run_record,
    save_figure,
    write_json,
)

SETTINGS = {  # name -> (environment additions, PackOptions.from_flat keys)
    "tuned": ({}, {}),
    "every thread": ({}, {"tune_threads": False}),
    "one thread": ({"NUMBA_NUM_THREADS": "1"}, {}),
}
LOADS = ("idle", "two busy loops", "another packing")


def _job(objects: int, cap: float, setting: str) -> tuple[str, dict, dict]:
    side = 60.0 * (objects / SIDE_60_COUNT) ** (1 / 3)
    params = {"extra_passes": [], "max_attempts": 1, **SETTINGS[setting][1]}
    return (f"box:{side:.3f}x{side:.3f}x{side:.3f}",
            {"type_scale": TYPE_SCALE, "time_budget": cap}, params)


def _start_load(load: str, setting: str, objects: int, cap: float, env: dict,
                meshes: Path) -> list[subprocess.Popen]:
    if load == "idle":
        return []
    if load == "two busy loops":
        cmd = [sys.executable, "-c", "while True: pass"]
        return [subprocess.Popen(cmd) for _ in range(2)]
    cmd = [sys.executable, __file__, "--worker", setting, "--objects", str(objects),
           "--cap", str(cap), "--meshes", str(meshes)]
    return [subprocess.Popen(cmd, env=env, start_new_session=True,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            p.kill()
        p.wait()


def measure(objects: int, cap: float, reps: int, env: dict, meshes: Path) -> list[dict]:
    rows = []
    for load in LOADS:
        for setting, (extra_env, _) in SETTINGS.items():
            run_env = {**env, **extra_env}
            container, kwargs, params = _job(objects, cap, setting)
            procs = _start_load(load, setting, objects, cap, run_env, meshes)
            try:
                time.sleep(3.0 if procs else 0.0)  # let the load start (imports, compiles)
                runs = [run_in_child(container, TYPES, 1, kwargs, params, env=run_env,
                                     meshes=meshes) for _ in range(reps)]
            finally:
                _stop(procs)
            place = [r["timings"]["phase1"] + r["timings"]["phase2"] for r in runs]
            row = {
                "load": load, "setting": setting, "placement_seconds": place,
                "median_seconds": statistics.median(place),
                "capped": sum(bool(r["stopped"]) for r in runs),
                "count": [r["metrics"]["count"] for r in runs],
                "density": [r["metrics"]["density"] for r in runs],
                "threads": [r["threads"] for r in runs],
            }
            rows.append(row)
            print(f"{load} / {setting}: placement {row['median_seconds']:.1f} s "
                  f"(runs {', '.join(f'{t:.1f}' for t in place)}), "
                  f"{row['count'][0]} objects, {row['capped']} capped", flush=True)
    return rows


def chart(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    rows = data["rows"]
    fig, ax = plt.subplots(figsize=(8, 4.6))
    width = 0.8 / len(SETTINGS)
    for k, setting in enumerate(SETTINGS):
        rs = [next(r for r in rows if r["load"] == ld and r["setting"] == setting)
              for ld in LOADS]
        x = np.arange(len(LOADS)) + (k - (len(SETTINGS) - 1) / 2) * width
        y = [r["median_seconds"] for r in rs]
        ax.bar(x, y, width, label=setting)
        for xi, r in zip(x, rs, strict=True):
            lo, hi = min(r["placement_seconds"]), max(r["placement_seconds"])
            ax.plot([xi, xi], [lo, hi], color="k", lw=1)
            n = len(r["placement_seconds"])
            capped = f"\n{r['capped']} of {n} capped" if r["capped"] else ""
            ax.annotate(f"{r['median_seconds']:.1f}{capped}",
                        (xi, r["median_seconds"]), fontsize=7, ha="center",
                        xytext=(0, 3), textcoords="offset points")
    ax.set_xticks(np.arange(len(LOADS)), LOADS)
    ax.set_yscale("log")
    ax.set_ylabel("placement time (s), median; bars: range")
    ax.set_title(f"Busy machine: {data['objects']} oranges and lemons in a cube, "
                 f"{data['reps']} runs each (2 cores)", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", type=int, default=1000)
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--cap", type=float, default=90.0,
                    help="placement time budget per run, seconds (default 90)")
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument("--worker", choices=list(SETTINGS), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.worker:  # the "another packing" load: pack in a loop until killed
        container, kwargs, params = _job(a.objects, a.cap, a.worker)
        while True:
            run_record(container, TYPES, 2, kwargs, params, a.meshes)
    out = RESULTS / "busy_machine.json"
    if a.report_only:
        data = json.loads(out.read_text())
    else:
        with tempfile.TemporaryDirectory() as cache:
            env = fresh_cache_env(cache)
            container, kwargs, params = _job(100, 1.0, "tuned")
            run_in_child(container, TYPES, 0, kwargs, params, env=env,
                         meshes=a.meshes)  # compile numba once
            rows = measure(a.objects, a.cap, a.reps, env, a.meshes)
        data = {"objects": a.objects, "reps": a.reps, "cap": a.cap, "types": TYPES,
                "cores": os.cpu_count(), "rows": rows}
        write_json(out, data)
    chart(data, RESULTS / "busy_machine.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
