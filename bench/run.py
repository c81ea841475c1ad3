"""Benchmarks of the packing engine: writes JSON and a chart to bench/results/.

    python bench/run.py                       # every scene, 3 seeds, plus one cold run each
    python bench/run.py --scene polyhedra-80 --seeds 1 2 3

Each run is its own process. The cold run starts with empty numba and approximation caches
(numba compiles, sphere packings are built); warm runs reuse them. Timings are wall-clock
seconds on this machine (2 cores, noisy): compare medians and ratios from one run only.
Meshes come from ../shared/meshes (beside the checkout), or --meshes DIR.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"

POLY = [f"polyhedra/convex5/polytope{i}.obj" for i in range(1, 6)]
FRUIT = [f"fruit/ycb_lowpoly/{n}.obj" for n in
         ("011_banana", "012_strawberry", "014_lemon", "015_peach", "017_orange")]

SCENES = {
    "polyhedra-80": {
        "container": "box:43.4338x41.8435x45.0059", "types": POLY,
        "kwargs": {"time_budget": 120.0},
        "bars": {"density": 0.455, "seconds": 139.0},
        "reference": "Romanova et al. 2018: 80 objects (60.6%); paper: 78 objects, 45.5%, "
                     "139 s on 12 cores",
    },
    "fruit-in-bunny": {
        "container": "containers/bunny.obj", "types": FRUIT,
        "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 280.0},
        "bars": {"density": 0.50, "tvd": 0.1, "nni": 1.0, "seconds": 300.0},
        "reference": "issue bar: >= 50% certified, TVD <= 0.1, NNI >= 1.0, <= 5 min",
    },
}


def run_one(scene: str, seed: int, meshes: Path, out: Path) -> None:
    """Child process: pack one scene with one seed and write a JSON record."""
    from jampacked.core.api import pack

    spec = SCENES[scene]
    container = spec["container"]
    if not container.startswith("box:"):
        container = str(meshes / container)
    types = [str(meshes / t) for t in spec["types"]]
    t0 = time.perf_counter()
    p = pack(container, types, seed=seed, **spec["kwargs"])
    wall = time.perf_counter() - t0
    rec = {
        "scene": scene, "seed": seed, "wall_seconds": wall, "timings": p.timings,
        "metrics": {k: v for k, v in p.metrics.items()},
        "certificate": p.certificate,
        "before_certification": p.params["repair"]["first"],
        "repair": {k: v for k, v in p.params["repair"].items() if k != "first"},
        "fidelity": p.params["fidelity"],
        "phase1": p.params["phase1"], "phase2": p.params["phase2"],
    }
    out.write_text(json.dumps(rec, indent=1))


def _child(scene: str, seed: int, meshes: Path, env: dict) -> dict:
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as f:
        out = Path(f.name)
    try:
        subprocess.run([sys.executable, __file__, "--child", scene, str(seed), str(meshes),
                        str(out)], check=True, env=env)
        return json.loads(out.read_text())
    finally:
        out.unlink(missing_ok=True)


def _summary(scene: str, cold: dict | None, warm: list[dict]) -> dict:
    spec = SCENES[scene]
    dens = [r["metrics"]["density"] for r in warm]
    secs = [r["wall_seconds"] for r in warm]
    s = {
        "scene": scene, "reference": spec["reference"], "bars": spec["bars"],
        "seeds": [r["seed"] for r in warm],
        "median_density": statistics.median(dens), "median_seconds": statistics.median(secs),
        "median_count": statistics.median([r["metrics"]["count"] for r in warm]),
        "median_tvd": statistics.median([r["metrics"]["tvd"] for r in warm]),
        "median_nni": statistics.median([r["metrics"]["nni_mean"] or 0 for r in warm]),
        "all_certified": all(r["certificate"]["certified"] for r in warm),
        "cold_seconds": cold["wall_seconds"] if cold else None,
        "cold_timings": cold["timings"] if cold else None,
        "runs": warm,
    }
    bars = spec["bars"]
    s["meets_bars"] = bool(
        s["all_certified"] and s["median_density"] >= bars["density"]
        and s["median_seconds"] <= bars["seconds"]
        and ("tvd" not in bars or s["median_tvd"] <= bars["tvd"])
        and ("nni" not in bars or s["median_nni"] >= bars["nni"]))
    return s


def _chart(summaries: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(summaries), figsize=(5.5 * len(summaries), 4.2),
                             squeeze=False)
    for ax, s in zip(axes[0], summaries, strict=True):
        for r in s["runs"]:
            ax.scatter(r["wall_seconds"], 100 * r["metrics"]["density"], color="tab:blue")
            ax.annotate(f"seed {r['seed']}", (r["wall_seconds"], 100 * r["metrics"]["density"]),
                        fontsize=7, xytext=(3, 3), textcoords="offset points")
        if s["cold_seconds"]:
            ax.axvline(s["cold_seconds"], color="tab:orange", ls=":", label="cold run time")
        ax.axhline(100 * s["bars"]["density"], color="tab:red", ls="--", label="density bar")
        ax.axvline(s["bars"]["seconds"], color="tab:red", ls="-.", label="time bar")
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("certified density (%)")
        ax.set_title(s["scene"])
        ax.set_xlim(left=0)
        ys = [100 * r["metrics"]["density"] for r in s["runs"]] + [100 * s["bars"]["density"]]
        ax.set_ylim(min(ys) - 3.0, max(ys) + 1.5)
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append", choices=sorted(SCENES))
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-start run")
    ap.add_argument("--report-only", action="store_true",
                    help="redraw the chart and table from bench/results/*.json, run nothing")
    ap.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        run_one(a.child[0], int(a.child[1]), Path(a.child[2]), Path(a.child[3]))
        return 0
    RESULTS.mkdir(parents=True, exist_ok=True)
    if a.report_only:
        summaries = [json.loads(f.read_text()) for f in sorted(RESULTS.glob("*.json"))
                     if f.stem in SCENES]
        _chart(summaries, RESULTS / "speed_density.png")
        _write_table(summaries, RESULTS / "README.md")
        return 0
    summaries = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=os.path.join(cache, "numba"),
                   JAMPACKED_CACHE=os.path.join(cache, "jampacked"))
        for scene in a.scene or list(SCENES):
            cold = None if a.no_cold else _child(scene, 0, a.meshes, env)
            warm = [_child(scene, s, a.meshes, env) for s in a.seeds]
            s = _summary(scene, cold, warm)
            summaries.append(s)
            (RESULTS / f"{scene}.json").write_text(json.dumps(s, indent=1))
            print(f"{scene}: median density {s['median_density']:.1%}, median "
                  f"{s['median_seconds']:.1f} s warm (cold {s['cold_seconds'] or 0:.1f} s), "
                  f"TVD {s['median_tvd']:.3f}, NNI {s['median_nni']:.2f}, "
                  f"certified {s['all_certified']}, bars met: {s['meets_bars']}", flush=True)
    _chart(summaries, RESULTS / "speed_density.png")
    _write_table(summaries, RESULTS / "README.md")
    return 0


def _write_table(summaries: list[dict], path: Path) -> None:
    """Markdown summary of the latest run (merged with scenes run earlier)."""
    lines = ["# Benchmark results", "",
             "Written by `python bench/run.py` on this project's 2-core machine; medians over "
             "the warm seeds, cold = first run with empty numba and approximation caches.", "",
             "| scene | seeds | objects | certified density | TVD | NNI | warm time (s) | "
             "cold time (s) | bars | bars met |", "|---|---|---|---|---|---|---|---|---|---|"]
    known = {}
    for f in sorted(RESULTS.glob("*.json")):
        if f.stem not in SCENES:  # other benchmarks' results live here too
            continue
        try:
            known[f.stem] = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
    for s in summaries:
        known[s["scene"]] = s
    for name in sorted(known):
        s = known[name]
        bars = ", ".join(f"{k} {v}" for k, v in s["bars"].items())
        lines.append(
            f"| {name} | {' '.join(map(str, s['seeds']))} | {s['median_count']:.0f} | "
            f"{s['median_density']:.1%} | {s['median_tvd']:.3f} | {s['median_nni']:.2f} | "
            f"{s['median_seconds']:.1f} | {s['cold_seconds'] or 0:.1f} | {bars} | "
            f"{'yes' if s['meets_bars'] else 'no'} |")
    lines += ["", "![speed against density](speed_density.png)", ""]
    path.write_text("\n".join(lines))


if __name__ == "__main__":
    sys.exit(main())
