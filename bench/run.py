"""The benchmark suite: one command, JSON and PNG in bench/results/.

    python bench/run.py                          # every part below (about 1.5-2 h here)
    python bench/run.py --part scenes --scene polyhedra-80 --seeds 1 2 3
    python bench/run.py --part fidelity growth   # some parts only
    python bench/run.py --report-only            # redraw charts and tables, run nothing

Parts: scenes (bench/scenes.py: every scene, seeds, a cold run each), fidelity (speed
against accuracy, bench/fidelity_sweep.py), growth (time against object count,
bench/growth.py), peer (Blender rigid bodies, bench/peer_bullet.py, needs bpy), stability
(bench/stability.py), profile (packed fraction against depth from the wall, fruit-in-bunny,
bench/density_profile.py), paper (tables beside the paper's figures, bench/paper.py; reads the
other results). Each run is its own process. Timings are wall-clock seconds on this
machine (2 cores, noisy): compare medians and ratios from one run only.

    python bench/run.py --part scenes --workers 2          # warm runs side by side
    python bench/run.py --part scenes --scheduler tcp://10.0.0.5:8786

--workers K / --scheduler ADDRESS: the scenes part's warm runs and the fidelity part's runs
(each still its own process) go to Dask workers; the cold runs stay here, one after
another. Runs side by side on one machine share its cores, so their times compare only
with runs made with the same worker count on the same machines: each run's record says
where it ran ("cluster").
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import (  # noqa: E402
    MESHES,
    RESULTS,
    SCENES,
    Runs,
    clearance_row,
    fresh_cache_env,
    median_phase_seconds,
    physical_cost,
    run_in_child,
    save_figure,
    write_json,
    write_text,
)

from jampacked.cli.args import UsageError  # noqa: E402
from jampacked.cli.cluster_args import add_cluster_arguments, cluster_client  # noqa: E402

PARTS = ("scenes", "fidelity", "growth", "peer", "stability", "profile", "paper")
#: scenes with bars run three seeds, the others one
BAR_SEEDS = [1, 2, 3]


def add_clearance(s: dict, meshes: Path = MESHES) -> None:
    """A clearance scene's summary gets its physical cost and the density it lost against
    its scene without ("without"), read from bench/results (None when not run yet)."""
    import json

    spec = SCENES[s["scene"]]
    c = spec["kwargs"]["clearance"]
    cost = s.get("clearance", {}).get("physical_cost")
    per_type = s.get("clearance", {}).get("physical_cost_per_type")
    if cost is None:
        got = physical_cost(spec["types"], spec["kwargs"].get("type_scale", 1.0), c,
                            meshes=meshes)
        cost, per_type = got["scene"], got["per_type"]
    f = RESULTS / f"{spec['without']}.json"
    without = json.loads(f.read_text())["median_density"] if f.exists() else None
    s["clearance"] = {**clearance_row(c, cost, s["median_density"], without),
                      "without": spec["without"], "physical_cost_per_type": per_type}


def summarise(scene: str, cold: dict | None, warm: list[dict]) -> dict:
    """Medians over the warm runs, bars checked, runs kept."""
    spec = SCENES[scene]
    med = statistics.median
    s = {
        "scene": scene, "reference": spec["reference"], "bars": spec.get("bars"),
        "container": spec["container"], "types": spec["types"], "kwargs": spec["kwargs"],
        "seeds": [r["seed"] for r in warm],
        "median_density": med([r["metrics"]["density"] for r in warm]),
        "median_seconds": med([r["wall_seconds"] for r in warm]),
        "median_count": med([r["metrics"]["count"] for r in warm]),
        "median_tvd": med([r["metrics"]["tvd"] for r in warm]),
        "median_nni": med([r["metrics"]["nni_mean"] or 0.0 for r in warm]),
        "median_phase_seconds": median_phase_seconds(warm),
        "worst_overlap_before_certification": max(
            r["before_certification"]["worst_overlap"] for r in warm),
        "worst_outside_before_certification": max(
            r["before_certification"]["worst_outside"] for r in warm),
        "moved": med([r["repair"]["moved"] for r in warm]),
        "removed": med([r["repair"]["removed"] for r in warm]),
        "all_certified": all(r["certificate"]["certified"] for r in warm),
        "cold_seconds": cold["wall_seconds"] if cold else None,
        "cold_timings": cold["timings"] if cold else None,
        "runs": warm,
    }
    bars = spec.get("bars")
    s["meets_bars"] = None if not bars else bool(
        s["all_certified"] and s["median_density"] >= bars["density"]
        and s["median_seconds"] <= bars["seconds"]
        and ("tvd" not in bars or s["median_tvd"] <= bars["tvd"])
        and ("nni" not in bars or s["median_nni"] >= bars["nni"]))
    return s


def run_scenes(names: list[str], seeds: list[int] | None, cold: bool, meshes: Path,
               runs: Runs | None = None) -> None:
    """Each scene's cold run (scenes with bars) and warm runs (its seeds), summarised into
    bench/results/<scene>.json. With `runs` on a cluster, the cold runs and the caches are
    prepared here first, then every warm run goes to the workers at once; each scene's file
    is written, in order, when its runs are back."""
    runs = runs or Runs()
    compiled = False
    with tempfile.TemporaryDirectory() as cache:
        env = fresh_cache_env(cache)

        def prepare(scene: str) -> dict | None:
            nonlocal compiled
            spec = SCENES[scene]
            args = (spec["container"], spec["types"])
            # the cold run (numba compiling, approximations built) for the scenes with bars,
            # in caches of its own: a scene run after another would find them filled
            first = None
            if cold and spec.get("bars"):
                with tempfile.TemporaryDirectory() as own:
                    first = run_in_child(*args, 0, spec["kwargs"], env=fresh_cache_env(own),
                                         meshes=meshes)
            if not compiled:  # the warm runs' caches: compile numba first
                run_in_child("box:30x30x30", SCENES["polyhedra-80"]["types"][:1], 0,
                             {"time_budget": 1.0}, env=env, meshes=meshes)
                compiled = True
            if first is not None:  # and build this scene's approximations there
                run_in_child(*args, 0, {**spec["kwargs"], "time_budget": 1.0}, env=env,
                             meshes=meshes)
            return first

        def start(scene: str) -> list:
            spec = SCENES[scene]
            use = seeds or (BAR_SEEDS if spec.get("bars") else [1])
            return [runs.start(spec["container"], spec["types"], s, spec["kwargs"], env=env,
                               meshes=meshes) for s in use]

        if runs.client is None:
            for scene in names:
                first = prepare(scene)
                _write_scene(scene, first, [runs.record(r) for r in start(scene)], meshes)
        else:
            firsts = [prepare(scene) for scene in names]
            started = [start(scene) for scene in names]
            for scene, first, rs in zip(names, firsts, started, strict=True):
                _write_scene(scene, first, [runs.record(r) for r in rs], meshes)


def _write_scene(scene: str, first: dict | None, warm: list[dict], meshes: Path) -> None:
    s = summarise(scene, first, warm)
    if "without" in SCENES[scene]:
        add_clearance(s, meshes)
    write_json(RESULTS / f"{scene}.json", s)
    print(f"{scene}: {s['median_count']:.0f} objects, density "
          f"{s['median_density']:.1%}, {s['median_seconds']:.1f} s warm (cold "
          f"{s['cold_seconds'] or 0:.1f} s), TVD {s['median_tvd']:.3f}, NNI "
          f"{s['median_nni']:.2f}, certified {s['all_certified']}, bars met: "
          f"{s['meets_bars']}", flush=True)


def load_summaries() -> list[dict]:
    import json

    out = []
    for name in SCENES:
        f = RESULTS / f"{name}.json"
        if f.exists():
            out.append(json.loads(f.read_text()))
    return out


def chart(summaries: list[dict], path: Path) -> None:
    """One panel per scene: certified density against wall time, each seed a point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = 3
    rows = (len(summaries) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.9 * rows), squeeze=False)
    for ax in axes.ravel()[len(summaries):]:
        ax.axis("off")
    for ax, s in zip(axes.ravel(), summaries, strict=False):
        xs = [r["wall_seconds"] for r in s["runs"]]
        ys = [100 * r["metrics"]["density"] for r in s["runs"]]
        ax.scatter(xs, ys, color="tab:blue", label="warm run (seed)")
        for r, x, y in zip(s["runs"], xs, ys, strict=True):
            ax.annotate(f"{r['seed']}", (x, y), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        if s.get("cold_seconds"):
            ax.axvline(s["cold_seconds"], color="tab:orange", ls=":", label="cold run")
        bars = s.get("bars")
        if bars:
            ax.axhline(100 * bars["density"], color="tab:red", ls="--", label="density bar")
            ax.axvline(bars["seconds"], color="tab:red", ls="-.", label="time bar")
            ys = ys + [100 * bars["density"]]
        ax.set_title(f"{s['scene']} ({s['median_count']:.0f} objects)", fontsize=10)
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel("certified density (%)")
        ax.set_xlim(left=0)
        ax.set_ylim(min(ys) - 3.0, max(ys) + 2.0)
        ax.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    save_figure(fig, path)


def write_table(summaries: list[dict], path: Path) -> None:
    """bench/results/README.md: the scene table, then links to every other part's output."""
    lines = [
        "# Benchmark results", "",
        "Written by `python bench/run.py` on this project's 2-core machine. Medians over the "
        "warm seeds; cold = the first run with empty numba and approximation caches. "
        "\"Before cert.\" is the worst exact overlap (pair intersection volume over the "
        "smaller object's) and wall violation (volume outside over the object's) of the "
        "placement the solver produced; certification then moved or removed objects until "
        "every check passed. The phase times are the kept attempt's; the warm time also "
        "covers the attempts not kept (`core/placement.py`). A scene marked * was last run "
        "before placement ran in attempts (its runs record none). The clearance column (issue 19): "
        "the clearance's physical cost (each type dilated by half the clearance, "
        "`core/dilation.py`; 1 - the types' volume over their dilated volume, mixed by the "
        "target shares) beside the density lost against the same scene without the "
        "clearance; the bar is that density x (1 - cost) - 1 point.", "",
        "| scene | seeds | objects | certified density | TVD | NNI | phase 1 / 2 / extra / "
        "certify (s) | warm time (s) | cold time (s) | before cert.: overlap, outside | moved, "
        "removed | clearance: physical cost, density lost | bars met |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        ph = s["median_phase_seconds"]
        met = {None: "no bars", True: "yes", False: "no"}[s["meets_bars"]]
        old = "" if all("attempts" in r for r in s["runs"]) else "*"
        lines.append(
            f"| {s['scene']}{old} | {' '.join(map(str, s['seeds']))} | {s['median_count']:.0f} | "
            f"{s['median_density']:.1%} | {s['median_tvd']:.3f} | {s['median_nni']:.2f} | "
            f"{ph['phase1']:.0f} / {ph['phase2']:.0f} / {ph.get('extra', 0):.0f} / "
            f"{ph['certify']:.1f} | "
            f"{s['median_seconds']:.1f} | "
            f"{'-' if s['cold_seconds'] is None else format(s['cold_seconds'], '.1f')} | "
            f"{s['worst_overlap_before_certification']:.1e}, "
            f"{s['worst_outside_before_certification']:.1e} | {s['moved']:.0f}, "
            f"{s['removed']:.0f} | {_clearance_cell(s)} | {met} |")
    lines += ["", "Bars: " + "; ".join(
        f"{s['scene']}: " + ", ".join(f"{k} {v}" for k, v in s["bars"].items())
        for s in summaries if s.get("bars")), "",
        "![certified density against time, per scene](speed_density.png)", "",
        "Other parts of the suite:", "",
        "- speed against accuracy: [fidelity.md](fidelity.md), "
        "![speed against accuracy](fidelity.png)",
        "- growth (the whole method): [growth.json](growth.json), "
        "![time against objects](growth.png); the paper's two phases only: "
        "[growth_paper.json](growth_paper.json), ![paper's phases](growth_paper.png); "
        "the whole method with a time budget (up to 100,000 objects): "
        "[growth_budgeted.json](growth_budgeted.json), "
        "![budgeted](growth_budgeted.png)",
        "- the paper's tables beside ours: [paper.md](paper.md)",
        "- Blender rigid bodies as a peer: [peer_bullet.json](peer_bullet.json), "
        "![peer](peer_bullet.png)",
        "- stability map: [stability.md](stability.md), ![stability](stability.png)",
        "- where density is lost (fruit-in-bunny): [density_profile.json]"
        "(density_profile.json), ![packed fraction against depth](density_profile.png)",
        "- export: [export.json](export.json); shell accuracy: "
        "[shell_accuracy.json](shell_accuracy.json)",
        "- the engine issue's runs (polyhedra-80 with 120 s, fruit-in-bunny with 280 s "
        "budgets; earlier code): [issue2/](issue2/)", ""]
    write_text(path, "\n".join(lines))


def _clearance_cell(s: dict) -> str:
    """The scene table's clearance column: c, the physical cost, the density lost against
    the scene without it, and whether issue 19's bar holds."""
    c = s.get("clearance")
    if not c:
        return "-"
    lost = "without not run" if c["density_lost"] is None else (
        f"lost {c['density_lost']:.1%} (bar {c['target']:.1%}: "
        f"{'met' if c['meets_target'] else 'not met'})")
    return f"{c['clearance']:g} mm: cost {c['physical_cost']:.1%}, {lost}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--part", nargs="+", choices=PARTS, default=list(PARTS))
    ap.add_argument("--scene", action="append", choices=list(SCENES),
                    help="scenes part: only these scenes (repeatable; default all)")
    ap.add_argument("--seeds", type=int, nargs="+",
                    help="scenes part: seeds (default 1 2 3 for scenes with bars, else 1)")
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--no-cold", action="store_true", help="skip the cold-start runs")
    ap.add_argument("--report-only", action="store_true",
                    help="redraw the charts and tables from bench/results, run nothing")
    add_cluster_arguments(ap, "the scenes part's warm runs and the fidelity part's runs",
                          reads_files=True)
    a = ap.parse_args(argv)
    RESULTS.mkdir(parents=True, exist_ok=True)
    parts = [] if a.report_only else a.part
    with contextlib.ExitStack() as stack:
        try:
            client = cluster_client(a, stack, needed="scenes" in parts)
        except UsageError as exc:
            ap.error(str(exc))
        if "scenes" in parts:
            run_scenes(a.scene or list(SCENES), a.seeds, not a.no_cold, a.meshes,
                       Runs(client))
    # the fidelity sweep starts (or joins) its own cluster
    dask = ([] if a.workers is None else ["--workers", str(a.workers)]) + (
        [] if a.scheduler is None else ["--scheduler", a.scheduler])
    for part in ("fidelity", "growth", "peer", "stability", "profile"):
        if part in parts:
            _run_part(part, a.meshes, dask if part == "fidelity" else [])
    summaries = load_summaries()
    for s in summaries:  # the scene without may have been re-run since
        if "without" in SCENES[s["scene"]]:
            add_clearance(s, a.meshes)
            write_json(RESULTS / f"{s['scene']}.json", s)
    if summaries:
        chart(summaries, RESULTS / "speed_density.png")
        write_table(summaries, RESULTS / "README.md")
    import paper

    paper.main([])
    return 0


def _run_part(part: str, meshes: Path, dask: list[str]) -> None:
    """Each part is its own script (and its own --help); run it as a child process."""
    import subprocess

    script = {"fidelity": "fidelity_sweep.py", "growth": "growth.py",
              "peer": "peer_bullet.py", "stability": "stability.py",
              "profile": "density_profile.py"}[part]
    if part == "peer":
        import importlib.util

        if importlib.util.find_spec("bpy") is None:
            print("peer: skipped, this Python has no bpy (pip install 'bpy>=4.5,<4.6' on "
                  "Python 3.11, as the test extra does)", flush=True)
            return
    extra = [] if part == "peer" else ["--meshes", str(meshes)]  # peer: the bundled scene
    extra += dask
    subprocess.run([sys.executable, str(Path(__file__).with_name(script)), *extra],
                   check=True)


if __name__ == "__main__":
    sys.exit(main())
