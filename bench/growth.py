"""Growth: time and peak memory against the number of objects, per phase, on log-log axes.

    python bench/growth.py [--method full|paper|budgeted] [--counts N ...] [--fit-from N]
                           [--seed N] [--out STEM]

The scene: oranges and lemons (YCB low-poly, x100: 6-7 mm) in a cube whose side is chosen
for about N objects, automatic fidelity, one attempt; above 1500 expected objects auto uses
24 spheres per type instead of 64, which the chart labels. Each size is its own process with
warm caches; its peak resident memory is recorded. Fits t = a * n^k per phase by least
squares on the logs, over the runs with at least --fit-from objects. The default sizes and
fit range are each method's (`DEFAULTS`): the whole method's extra passes grow as about
n^1.7, so its 800-object cube already takes about 20 minutes here (docs/benchmarks.md).

--method full (default): the whole method without a time budget, as a user runs it: phase 1,
phase 2, the extra cavity passes and certification; writes bench/results/growth.json and
growth.png (with the paper method's total for comparison when growth_paper.json exists).
--method paper: the paper's two phases only (no extra passes), with --cap as pack's time
budget (a run that passes it is stopped and marked); writes growth_paper.json and
growth_paper.png.
--method budgeted: the whole method with a time budget per size (--budgets, one per count;
default `BUDGETS`), as a user runs a large packing: the passes fill holes until the budget
ends, attempts as pack chooses them; writes growth_budgeted.json and growth_budgeted.png.
Its total times follow the budgets, so their fits say little. What scales is the time the
run took to reach a density (`LEVELS`: placed density of full-size objects before
certification, from the phases' progress reports, counted from pack's start): each run
records it per level, and the fits give its exponent over the runs that reached the level
(a level some run in the fit range never reached gets no fit). The chart's right panel.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import MESHES, RESULTS, fresh_cache_env, run_in_child, save_figure, write_json  # noqa: E402, I001

TYPES = ["fruit/ycb_lowpoly/017_orange.obj", "fruit/ycb_lowpoly/014_lemon.obj"]
TYPE_SCALE = 100.0
#: a 60 mm cube held 646 of them (44.7%) in a trial run: side = 60 * (N / 646)^(1/3)
SIDE_60_COUNT = 646
PHASES = {"full": ("approximate", "phase1", "phase2", "extra", "certify", "total"),
          "paper": ("approximate", "phase1", "phase2", "certify", "total")}
PHASES["budgeted"] = PHASES["full"]
#: per method: (default target counts, default --fit-from)
DEFAULTS = {"full": ([100, 200, 400, 800], 100),
            "paper": ([1000, 3000, 10000, 30000, 100000], 100),
            "budgeted": ([1000, 3000, 5000, 10000, 30000, 100000], 1000)}
#: budgeted method: default placement budget (s) per target count; 100,000 objects get
#: 500 s, so that with certification the run fits issue 21's 10 minutes
BUDGETS = {1000: 120.0, 3000: 180.0, 5000: 240.0, 10000: 240.0, 30000: 300.0,
           100000: 500.0}
#: budgeted method: placed densities whose time to reach is recorded and fitted
LEVELS = (0.55, 0.57, 0.58, 0.59, 0.60)
STEMS = {"full": "growth", "paper": "growth_paper", "budgeted": "growth_budgeted"}
COLORS = {"approximate": "tab:gray", "phase1": "tab:blue", "phase2": "tab:green",
          "extra": "tab:orange", "certify": "tab:purple", "total": "k"}


def fit(n: np.ndarray, t: np.ndarray) -> tuple[float, float] | None:
    """(k, a) of t = a n^k by least squares on logs; None with fewer than 2 usable points."""
    ok = (n > 0) & (t > 0)
    if ok.sum() < 2:
        return None
    k, loga = np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)
    return float(k), float(np.exp(loga))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+",
                    help="target object counts (default: " + "; ".join(
                        f"{m} {' '.join(map(str, DEFAULTS[m][0]))}" for m in DEFAULTS) + ")")
    ap.add_argument("--method", choices=("full", "paper", "budgeted"), default="full")
    ap.add_argument("--cap", type=float, default=900.0,
                    help="paper method: placement time budget per run, seconds (default 900)")
    ap.add_argument("--budgets", type=float, nargs="+",
                    help="budgeted method: placement budget (s) per count, in --counts' "
                         "order (default: BUDGETS, the nearest count's)")
    ap.add_argument("--fit-from", type=int,
                    help="fit the runs with at least this many objects (default: " +
                         ", ".join(f"{m} {DEFAULTS[m][1]}" for m in DEFAULTS) + ")")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", metavar="STEM",
                    help="results' file stem in bench/results (default: the method's, e.g. "
                         "growth_budgeted): other seeds beside the default run")
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--report-only", action="store_true")
    a = ap.parse_args(argv)
    counts, fit_from = DEFAULTS[a.method]
    a.counts = a.counts or counts
    a.fit_from = fit_from if a.fit_from is None else a.fit_from
    if a.budgets is not None and len(a.budgets) != len(a.counts):
        ap.error(f"--budgets gives {len(a.budgets)} budgets for {len(a.counts)} counts")
    budgets = a.budgets or [BUDGETS[min(BUDGETS, key=lambda c: abs(c - n))]
                            for n in a.counts]
    stem = a.out or STEMS[a.method]
    out = RESULTS / f"{stem}.json"
    if a.report_only:
        data = json.loads(out.read_text())
    else:
        runs = []
        with tempfile.TemporaryDirectory() as cache:
            env = fresh_cache_env(cache)
            run_in_child("box:20x20x20", TYPES, 0, {"type_scale": TYPE_SCALE,
                                                    "time_budget": 1.0}, env=env,
                         meshes=a.meshes)  # compile numba once
            for n, budget in zip(a.counts, budgets, strict=True):
                side = 60.0 * (n / SIDE_60_COUNT) ** (1 / 3)
                if a.method == "paper":
                    # one attempt: the cap is a budget, and a budget's spare time would go
                    # to more attempts, not to these phases
                    kwargs = {"type_scale": TYPE_SCALE, "time_budget": a.cap}
                    params = {"extra_passes": [], "max_attempts": 1}
                elif a.method == "budgeted":
                    kwargs, params = {"type_scale": TYPE_SCALE, "time_budget": budget}, {}
                else:  # no budget: one attempt, its extra passes run to their end
                    kwargs, params = {"type_scale": TYPE_SCALE}, {}
                rec = run_in_child(f"box:{side:.3f}x{side:.3f}x{side:.3f}", TYPES, a.seed,
                                   kwargs, params, env=env, meshes=a.meshes)
                rec["target"] = n
                rec["side"] = side
                if a.method == "budgeted":
                    rec["budget"] = budget
                rec["load"] = os.getloadavg()
                runs.append(rec)
                print(f"target {n}: {rec['metrics']['count']} objects, "
                      f"{rec['wall_seconds']:.1f} s, density {rec['metrics']['density']:.1%}, "
                      f"peak {rec['peak_rss_mb']:.0f} MiB, load {rec['load'][0]:.1f}"
                      f"{_stop_note(rec)}", flush=True)
                # each size is saved as it ends: the large ones take long
                write_json(out, {"method": a.method, "types": TYPES,
                                 "type_scale": TYPE_SCALE, "cap": a.cap, "runs": runs})
        data = {"method": a.method, "types": TYPES, "type_scale": TYPE_SCALE, "cap": a.cap,
                "runs": runs}
    data["fit_from"] = a.fit_from
    data["fits"] = fits(data, PHASES[data.get("method", "paper")], a.fit_from)
    if data.get("method") == "budgeted":
        for r in data["runs"]:
            r["time_to_density"] = times_to_levels(r.get("density_trace", []))
        data["level_fits"] = level_fits(data["runs"], a.fit_from)
    write_json(out, data)
    other = RESULTS / "growth_paper.json"
    paper = json.loads(other.read_text()) if a.method == "full" and other.exists() else None
    _chart(data, RESULTS / f"{stem}.png", paper)
    return 0


def fits(data: dict, phases: tuple[str, ...], fit_from: int) -> dict:
    """Per phase (and peak memory "peak_rss_mb", CPU time "cpu_seconds"): exponent and
    coefficient of the fit over the runs with at least fit_from objects, or None."""
    runs = [r for r in data["runs"] if r["metrics"]["count"] >= fit_from]
    n = np.array([r["metrics"]["count"] for r in runs], float)
    out = {}
    for ph in phases:
        f = fit(n, np.array([r["timings"].get(ph, 0.0) for r in runs], float))
        out[ph] = None if f is None else {"exponent": f[0], "coefficient": f[1]}
    for key in ("peak_rss_mb", "cpu_seconds"):
        f = fit(n, np.array([r.get(key, 0.0) for r in runs], float))
        out[key] = None if f is None else {"exponent": f[0], "coefficient": f[1]}
    return out


def time_to_density(trace: list, level: float) -> float | None:
    """Seconds from pack's start to the first progress report at a placed density of at
    least level (a fraction), or None if the run never reached it. trace: (s, density)."""
    for t, d in trace:
        if d >= level:
            return float(t)
    return None


def times_to_levels(trace: list) -> dict[str, float | None]:
    """`time_to_density` per `LEVELS` entry, keyed by the level as text ("0.58")."""
    return {f"{lv:.2f}": time_to_density(trace, lv) for lv in LEVELS}


def level_fits(runs: list[dict], fit_from: int) -> dict[str, dict]:
    """Per level: the exponent and coefficient of time-to-reach against objects placed over
    the runs with at least fit_from objects, and how many of them reached it; no fit (None)
    unless all of them did, since a run that never reached it has no time to fit."""
    runs = [r for r in runs if r["metrics"]["count"] >= fit_from]
    out = {}
    for key in (f"{lv:.2f}" for lv in LEVELS):
        t = [r["time_to_density"].get(key) for r in runs]
        ok = [x is not None for x in t]
        f = None
        if all(ok):
            f = fit(np.array([r["metrics"]["count"] for r in runs], float), np.array(t, float))
        out[key] = {"reached": sum(ok), "runs": len(runs),
                    "fit": None if f is None else {"exponent": f[0], "coefficient": f[1]}}
    return out


def _stop_note(rec: dict) -> str:
    """What a run's end says beside its figures: its budget (budgeted method), or that the
    paper method's cap stopped it."""
    if "budget" in rec:
        return f", {rec['budget']:.0f} s budget"
    return ", stopped by the cap" if rec["stopped"] else ""


def _chart(data: dict, path: Path, paper: dict | None = None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    method = data.get("method", "paper")
    n = np.array([r["metrics"]["count"] for r in data["runs"]], float)
    levels = data.get("level_fits")
    if levels:
        fig, (ax, axm, axl) = plt.subplots(1, 3, figsize=(16, 5), width_ratios=(3, 2, 3))
    else:
        fig, (ax, axm) = plt.subplots(1, 2, figsize=(11, 5), width_ratios=(3, 2))
    for ph in PHASES[method]:
        color = COLORS[ph]
        t = np.array([r["timings"].get(ph, 0.0) for r in data["runs"]], float)
        f = data["fits"].get(ph)
        label = ph if f is None else f"{ph}: t ~ n^{f['exponent']:.2f}"
        ax.loglog(n, np.maximum(t, 1e-3), "o", color=color, label=label)
        if f is not None:
            xs = np.geomspace(max(n.min(), data.get("fit_from", 0)), n.max(), 20)
            ax.loglog(xs, f["coefficient"] * xs ** f["exponent"], "-", color=color, lw=1)
    cpu = np.array([r.get("cpu_seconds", np.nan) for r in data["runs"]], float)
    f = data["fits"].get("cpu_seconds")
    if f is not None:
        ax.loglog(n, cpu, "s", mfc="none", color="k",
                  label=f"CPU time (all threads): ~ n^{f['exponent']:.2f}")
    if paper is not None:
        pn = np.array([r["metrics"]["count"] for r in paper["runs"]], float)
        pt = np.array([r["timings"]["total"] for r in paper["runs"]], float)
        ax.loglog(pn, pt, "x--", color="tab:red", lw=1, label="paper's two phases: total")
    for i, (r, x) in enumerate(zip(data["runs"], n, strict=True)):
        # auto fidelity uses fewer spheres above MANY_OBJECTS expected objects
        note = f"{r['metrics']['density']:.1%}, {r['fidelity_detail']['spheres']} sph"
        note += _stop_note(r)
        # above and below in turn: neighbouring sizes' notes would overlap
        ax.annotate(note, (x, r["timings"]["total"]), fontsize=7,
                    xytext=(-20, 6 if i % 2 == 0 else -14), textcoords="offset points")
    ax.set_xlabel("objects placed")
    ax.set_ylabel("wall time (s)")
    title = {"full": "the whole method, no budget", "paper": "paper's phases",
             "budgeted": "the whole method, time budget"}[method]
    ax.set_title(f"Growth: oranges and lemons in a cube ({title}, 2 cores)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    mem = np.array([r.get("peak_rss_mb", np.nan) for r in data["runs"]], float)
    f = data["fits"].get("peak_rss_mb")
    axm.loglog(n, mem, "o", color="tab:brown",
               label="peak RSS" if f is None else f"peak RSS ~ n^{f['exponent']:.2f}")
    axm.set_xlabel("objects placed")
    axm.set_ylabel("peak resident memory (MiB)")
    axm.legend(fontsize=8)
    axm.grid(True, which="both", alpha=0.3)
    if levels:
        _levels_panel(axl, data, levels)
    fig.tight_layout()
    save_figure(fig, path)


def _levels_panel(ax, data: dict, levels: dict) -> None:
    """Time to reach each placed density against objects placed, with the fits."""
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    for i, (key, lf) in enumerate(levels.items()):
        color = cmap(i / max(len(levels) - 1, 1))
        pts = [(r["metrics"]["count"], r["time_to_density"][key]) for r in data["runs"]
               if r["time_to_density"].get(key) is not None]
        if not pts:
            continue
        n, t = np.array(pts, float).T
        f = lf["fit"]
        label = f"{float(key):.0%}: " + (f"~ n^{f['exponent']:.2f}" if f else
                                         f"reached by {lf['reached']} of {lf['runs']}")
        ax.loglog(n, t, "o", color=color, label=label)
        if f is not None:
            xs = np.geomspace(max(n.min(), data.get("fit_from", 0)), n.max(), 20)
            ax.loglog(xs, f["coefficient"] * xs ** f["exponent"], "-", color=color, lw=1)
    ax.set_xlabel("objects placed")
    ax.set_ylabel("time to reach the density (s)")
    ax.set_title("Time to a placed density (before certification)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)


if __name__ == "__main__":
    sys.exit(main())
