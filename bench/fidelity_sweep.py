"""Speed against accuracy: the solver's resolution and iteration caps, swept.

    python bench/fidelity_sweep.py [--scene fruit-in-torus] [--seeds 1 2]

For each scene, every configuration packs with the full pipeline under the scene's time
budget and records its density over time (full-size objects, before certification, from
the progress messages) and its certified result. Configurations: the presets (low, medium,
high), the automatic choice, and one knob at a time from medium: spheres and surface
points per type, container grid cells per smallest radius, solver iteration caps.

The "scans" scene packs the 16k-face YCB scans, where auto is compared with fixed high
fidelity: the time each needs to reach the density both reach.

Recorded per run: wall time per phase, certified density, the worst exact overlap and wall
violation before certification, objects certification moved or removed. Writes
bench/results/fidelity.json, fidelity.png (density against time with the best envelope,
auto marked; time against the worst pre-certification overlap) and fidelity.md. Each run
is its own process with warm caches (one throw-away run compiles numba first).

With --workers K or --scheduler ADDRESS each scene's runs go to Dask workers side by side
(each still its own process). Runs side by side on one machine share its cores, so their
times compare only with runs made with the same worker count on the same machines: each
run's record says where it ran ("cluster").
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import (  # noqa: E402
    MESHES,
    RESULTS,
    SCENES,
    Runs,
    fresh_cache_env,
    median_phase_seconds,
    run_in_child,
    save_figure,
    write_json,
    write_text,
)

from jampacked.cli.args import UsageError  # noqa: E402
from jampacked.cli.cluster_args import add_cluster_arguments, cluster_client  # noqa: E402

#: name -> (fidelity argument, PackOptions.from_flat keys)
CONFIGS: dict[str, tuple[str, dict]] = {
    "low": ("low", {}),
    "medium": ("medium", {}),
    "high": ("high", {}),
    "auto": ("auto", {}),
    "spheres 24": ("medium", {"spheres": 24}),
    "spheres 160": ("medium", {"spheres": 160}),
    "points 96": ("medium", {"surface_points": 96}),
    "points 192": ("medium", {"surface_points": 192}),
    "container 3/r": ("medium", {"container_cells": 3.0}),
    "container 6/r": ("medium", {"container_cells": 6.0}),
    "iterations x0.5": ("medium", {"phase1_iterations": 15, "phase2_iterations": 40}),
    "iterations x2": ("medium", {"phase1_iterations": 60, "phase2_iterations": 160}),
}
#: the YCB google_16k scans (16384 faces each): auto against fixed high fidelity
SCANS = {
    "container": "containers/spot.obj",
    "types": [f"fruit/ycb/{n}.ply" for n in
              ("013_apple", "014_lemon", "015_peach", "017_orange", "018_plum")],
    "kwargs": {"container_size": 200.0, "type_scale": 300.0, "time_budget": 120.0},
    "configs": ["auto", "high"],
}
DEFAULT_SCENES = ["fruit-in-torus", "polyhedra-80", "scans"]


def _scene(name: str) -> tuple[dict, list[str]]:
    if name == "scans":
        return SCANS, SCANS["configs"]
    return SCENES[name], list(CONFIGS)


def sweep(scene: str, seeds: list[int], env: dict, meshes: Path,
          only: list[str] | None = None, where: Runs | None = None) -> list[dict]:
    """One row per configuration (its runs over `seeds`); on a cluster (`where`) every
    configuration's runs of the scene are submitted at once, the rows made in order."""
    where = where or Runs()
    spec, configs = _scene(scene)
    configs = [c for c in configs if not only or c in only]

    def start(name: str) -> list:
        fidelity, over = CONFIGS[name]
        return [where.start(spec["container"], spec["types"], s,
                            {**spec["kwargs"], "fidelity": fidelity}, over, env=env,
                            meshes=meshes) for s in seeds]

    started = [start(name) for name in configs] if where.client is not None else None
    rows = []
    for k, name in enumerate(configs):
        fidelity, over = CONFIGS[name]
        runs = [where.record(r) for r in (started[k] if started else start(name))]
        med = statistics.median
        row = {
            "scene": scene, "config": name, "fidelity": fidelity, "overrides": over,
            "chosen": runs[0]["fidelity_detail"],
            "seconds": med([r["wall_seconds"] for r in runs]),
            "density": med([r["metrics"]["density"] for r in runs]),
            "count": med([r["metrics"]["count"] for r in runs]),
            "worst_overlap": med([r["before_certification"]["worst_overlap"] for r in runs]),
            "worst_outside": med([r["before_certification"]["worst_outside"] for r in runs]),
            "moved": med([r["repair"]["moved"] for r in runs]),
            "removed": med([r["repair"]["removed"] for r in runs]),
            "phase_seconds": median_phase_seconds(runs),
            "runs": runs,
        }
        rows.append(row)
        print(f"{scene} / {name}: {row['seconds']:.1f} s, density {row['density']:.1%}, "
              f"overlap before cert. {row['worst_overlap']:.1e}, removed {row['removed']:.0f}",
              flush=True)
    return rows


def best_by(row: dict, times: np.ndarray) -> np.ndarray:
    """Median over seeds of the best density reached by each time (before certification)."""
    per_run = []
    for r in row["runs"]:
        tr = np.array(r["density_trace"] or [(r["wall_seconds"], 0.0)], float)
        best = np.maximum.accumulate(tr[:, 1])
        idx = np.searchsorted(tr[:, 0], times, side="right") - 1
        per_run.append(np.where(idx >= 0, best[np.maximum(idx, 0)], 0.0))
    return np.median(np.array(per_run), axis=0)


def time_to_reach(row: dict, density: float) -> float | None:
    """Median over seeds of the first time the density trace reaches `density`."""
    out = []
    for r in row["runs"]:
        hit = [t for t, d in (r["density_trace"] or []) if d >= density]
        if not hit:
            return None
        out.append(hit[0])
    return float(statistics.median(out))


def trusted(row: dict) -> bool:
    """A configuration whose placing density is real: certification removed nothing (its
    trace counts objects that were later removed otherwise)."""
    return row["removed"] == 0


def envelope_gap(rows: list[dict], config: str = "auto") -> dict:
    """How far `config` is below the best configuration, over the time axis.

    Returns the mean and largest gap (density points) between the best density any trusted
    configuration reached by time t and `config`'s, for t from a quarter of the budget to
    the end, and the final certified densities' ranking."""
    mine = next(r for r in rows if r["config"] == config)
    end = max(r["seconds"] for r in rows)
    times = np.linspace(0.25 * end, end, 60)
    curves = {r["config"]: best_by(r, times) for r in rows if trusted(r) or r is mine}
    best = np.max(np.array(list(curves.values())), axis=0)
    gap = 100 * (best - curves[config])
    final = sorted(rows, key=lambda r: -r["density"])
    return {"mean_gap_points": float(gap.mean()), "max_gap_points": float(gap.max()),
            "final_rank": 1 + [r["config"] for r in final].index(config),
            "final_best": final[0]["config"], "final_density": mine["density"],
            "final_best_density": final[0]["density"]}


def chart(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(len(scenes), 2, figsize=(12, 4.4 * len(scenes)), squeeze=False)
    cmap = plt.get_cmap("tab10")
    for (ax1, ax2), scene in zip(axes, scenes, strict=True):
        rs = [r for r in rows if r["scene"] == scene]
        end = max(r["seconds"] for r in rs)
        times = np.linspace(0, end, 200)
        best = np.max(np.array([best_by(r, times) for r in rs if trusted(r)]), axis=0)
        ax1.plot(times, 100 * best, color="0.75", lw=6, zorder=0,
                 label="best (certification removed none)")
        for k, r in enumerate(rs):
            auto = r["config"] == "auto"
            color = "tab:red" if auto else cmap(k % 10)
            ax1.plot(times, 100 * best_by(r, times), color=color, lw=2.2 if auto else 1,
                     ls="-" if trusted(r) else ":",
                     label=r["config"] + ("" if trusted(r) else f" ({r['removed']:.0f} removed)"))
            ax1.scatter([r["seconds"]], [100 * r["density"]], color=color,
                        marker="*" if auto else "o", s=120 if auto else 25, zorder=3)
            ax2.scatter(r["seconds"], max(r["worst_overlap"], 1e-7), color=color,
                        marker="*" if auto else "o", s=120 if auto else 30)
            ax2.annotate(r["config"], (r["seconds"], max(r["worst_overlap"], 1e-7)),
                         fontsize=7, xytext=(4, 2), textcoords="offset points")
        ax1.set_title(f"{scene}: density while placing, certified (dots)",
                      fontsize=10)
        ax1.set_xlabel("wall time (s)")
        ax1.set_ylabel("density (%)")
        ax1.set_ylim(bottom=max(0.0, 100 * float(best.max()) - 25))
        ax1.legend(fontsize=6, ncol=2, loc="lower right")
        ax2.set_yscale("log")
        ax2.axhline(1e-4, color="tab:red", ls=":", lw=1, label="certification tolerance")
        ax2.set_title(f"{scene}: time against worst overlap before certification",
                      fontsize=10)
        ax2.set_xlabel("wall time (s)")
        ax2.set_ylabel("worst pair overlap / object volume")
        ax2.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def table(rows: list[dict], summary: dict, path: Path) -> None:
    lines = ["# Speed against accuracy", "",
             "`python bench/fidelity_sweep.py`: the full pipeline under each scene's time "
             "budget, warm caches, this 2-core machine. Overlap and outside: worst exact "
             "values before certification (fraction of the object's volume; certification "
             "then moves or removes objects until every value is <= 1e-4).", "",
             "| scene | config | spheres / grid cells / surface points / container cells | "
             "time (s) | certified density | objects | overlap before cert. | outside before "
             "cert. | moved, removed |", "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        c = r["chosen"]
        knobs = (f"{c['spheres']} / {c['grid_cells']} / {c['surface_points']} / "
                 f"{c['container_cells']:g}")
        lines.append(
            f"| {r['scene']} | {r['config']} | {knobs} | {r['seconds']:.1f} | "
            f"{r['density']:.1%} | {r['count']:.0f} | {r['worst_overlap']:.1e} | "
            f"{r['worst_outside']:.1e} | {r['moved']:.0f}, {r['removed']:.0f} |")
    lines += ["", "## Where auto sits", ""]
    for scene, s in summary.items():
        if "mean_gap_points" in s:
            lines.append(
                f"- {scene}: auto's density while placing is on average "
                f"{s['mean_gap_points']:.1f} points (at most {s['max_gap_points']:.1f}) below "
                f"the best configuration at the same time; its certified density ranks "
                f"{s['final_rank']} of the configurations ({s['final_density']:.1%}; best "
                f"{s['final_best']} {s['final_best_density']:.1%}).")
        if "time_saved" in s:
            t = s["time_saved"]
            lines.append(
                f"- {scene}: to reach {t['density']:.1%} auto took {t['auto_seconds']:.1f} s "
                f"and high {t['high_seconds']:.1f} s" if t["high_seconds"] is not None else
                f"- {scene}: high never reached auto's {t['density']:.1%} within the budget")
        reasons = s.get("auto_reasons")
        if reasons is not None:
            lines.append(f"  - auto chose: {'; '.join(reasons) or 'medium, unchanged'}.")
    write_text(path, "\n".join(lines) + "\n")


def summarise(rows: list[dict]) -> dict:
    out = {}
    for scene in dict.fromkeys(r["scene"] for r in rows):
        rs = [r for r in rows if r["scene"] == scene]
        auto = next((r for r in rs if r["config"] == "auto"), None)
        if auto is None:
            continue
        s = envelope_gap(rs) if len(rs) > 2 else {}
        s["auto_reasons"] = auto["chosen"]["reasons"]
        high = next((r for r in rs if r["config"] == "high"), None)
        if high is not None:
            # the density both reach: the lower of their best pre-certification densities
            d = min(max(d for _, d in r["density_trace"] or [(0, 0.0)])
                    for r in auto["runs"] + high["runs"])
            s["time_saved"] = {"density": d, "auto_seconds": time_to_reach(auto, d),
                               "high_seconds": time_to_reach(high, d)}
        out[scene] = s
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append", choices=[*SCENES, "scans"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--config", action="append", choices=list(CONFIGS),
                    help="only these configurations, replacing their rows in the last "
                         "results (repeatable)")
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--report-only", action="store_true")
    add_cluster_arguments(ap, "the configurations' runs", reads_files=True)
    a = ap.parse_args(argv)
    out = RESULTS / "fidelity.json"
    if a.report_only:
        import json

        rows = json.loads(out.read_text())["rows"]
    else:
        rows = []
        with tempfile.TemporaryDirectory() as cache, contextlib.ExitStack() as stack:
            try:
                where = Runs(cluster_client(a, stack))
            except UsageError as exc:
                ap.error(str(exc))
            env = fresh_cache_env(cache)
            run_in_child("box:30x30x30", SCENES["polyhedra-80"]["types"], 0,  # compile numba
                         {"time_budget": 1.0}, env=env, meshes=a.meshes)
            for scene in a.scene or DEFAULT_SCENES:
                rows += sweep(scene, a.seeds, env, a.meshes, a.config, where)
        if a.config and out.exists():
            import json

            new = {(r["scene"], r["config"]): r for r in rows}
            old = json.loads(out.read_text())["rows"]
            rows = [new.pop((r["scene"], r["config"]), r) for r in old] + list(new.values())
    summary = summarise(rows)
    write_json(out, {"seeds": a.seeds, "rows": rows, "summary": summary})
    chart(rows, RESULTS / "fidelity.png")
    table(rows, summary, RESULTS / "fidelity.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
