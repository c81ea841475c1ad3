"""Growth: time against the number of objects, per phase, on log-log axes.

    python bench/growth.py [--counts 100 300 1000 2000 5000]

The scene: oranges and lemons (YCB low-poly, x100: 6-7 mm) in a cube whose side is chosen
for about N objects, the paper's two phases only (no extra cavity passes), automatic
fidelity, one attempt (the cap is pack's time budget: a run that passes --cap seconds is
stopped and marked); above 1500 expected objects auto uses 24 spheres per type instead of 64, which
the chart labels. Each size is its own process with warm caches. Fits t = a * n^k per phase by least
squares on the logs. Writes bench/results/growth.json and growth.png.
"""

from __future__ import annotations

import argparse
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
PHASES = ("approximate", "phase1", "phase2", "certify", "total")


def fit(n: np.ndarray, t: np.ndarray) -> tuple[float, float] | None:
    """(k, a) of t = a n^k by least squares on logs; None with fewer than 2 usable points."""
    ok = (n > 0) & (t > 0)
    if ok.sum() < 2:
        return None
    k, loga = np.polyfit(np.log(n[ok]), np.log(t[ok]), 1)
    return float(k), float(np.exp(loga))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[100, 300, 1000, 2000, 5000])
    ap.add_argument("--cap", type=float, default=900.0,
                    help="placement time budget per run, seconds (default 900)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--report-only", action="store_true")
    a = ap.parse_args(argv)
    out = RESULTS / "growth.json"
    if a.report_only:
        import json

        data = json.loads(out.read_text())
    else:
        runs = []
        with tempfile.TemporaryDirectory() as cache:
            env = fresh_cache_env(cache)
            run_in_child("box:20x20x20", TYPES, 0, {"type_scale": TYPE_SCALE,
                                                    "time_budget": 1.0}, env=env,
                         meshes=a.meshes)  # compile numba once
            for n in a.counts:
                side = 60.0 * (n / SIDE_60_COUNT) ** (1 / 3)
                rec = run_in_child(f"box:{side:.3f}x{side:.3f}x{side:.3f}", TYPES, a.seed,
                                   {"type_scale": TYPE_SCALE, "time_budget": a.cap},
                                   # one attempt: the cap is a budget, and a budget's spare
                                   # time would go to more attempts, not to these phases
                                   {"extra_passes": [], "max_attempts": 1}, env=env,
                                   meshes=a.meshes)
                rec["target"] = n
                rec["side"] = side
                runs.append(rec)
                print(f"target {n}: {rec['metrics']['count']} objects, "
                      f"{rec['wall_seconds']:.1f} s, density {rec['metrics']['density']:.1%}"
                      f"{', stopped by the cap' if rec['stopped'] else ''}", flush=True)
        data = {"types": TYPES, "type_scale": TYPE_SCALE, "cap": a.cap, "runs": runs}
    n = np.array([r["metrics"]["count"] for r in data["runs"]], float)
    data["fits"] = {}
    for ph in PHASES:
        f = fit(n, np.array([r["timings"][ph] for r in data["runs"]], float))
        data["fits"][ph] = None if f is None else {"exponent": f[0], "coefficient": f[1]}
    write_json(out, data)
    _chart(data, RESULTS / "growth.png")
    return 0


def _chart(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([r["metrics"]["count"] for r in data["runs"]], float)
    fig, ax = plt.subplots(figsize=(7, 5))
    for ph, color in zip(PHASES, ("tab:gray", "tab:blue", "tab:green", "tab:purple", "k"),
                         strict=True):
        t = np.array([r["timings"][ph] for r in data["runs"]], float)
        f = data["fits"][ph]
        label = ph if f is None else f"{ph}: t ~ n^{f['exponent']:.2f}"
        ax.loglog(n, np.maximum(t, 1e-3), "o", color=color, label=label)
        if f is not None:
            xs = np.geomspace(n.min(), n.max(), 20)
            ax.loglog(xs, f["coefficient"] * xs ** f["exponent"], "-", color=color, lw=1)
    for r, x in zip(data["runs"], n, strict=True):
        # auto fidelity uses fewer spheres above MANY_OBJECTS expected objects
        note = f"{r['fidelity_detail']['spheres']} spheres"
        if r["stopped"]:
            note += ", stopped by the cap"
        ax.annotate(note, (x, r["timings"]["total"]), fontsize=7, xytext=(-20, 6),
                    textcoords="offset points")
    ax.set_xlabel("objects placed")
    ax.set_ylabel("wall time (s)")
    ax.set_title("Growth: oranges and lemons in a cube (paper's phases, 2 cores)",
                 fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, path)


if __name__ == "__main__":
    sys.exit(main())
