"""The paper's Table 1 and Table 2, ours beside theirs, from the scene results.

    python bench/paper.py            # reads bench/results/<scene>.json, runs nothing

Table 1: TVD and NNI after phase 1 and after phase 2 (the paper's two phases), then after
our extra cavity passes and after certification. Table 2: objects, time and density. The
paper's own figure is given where this workspace has it: polyhedra-80 (78 objects, 45.5%,
139 s on a 12-core desktop, as the engine issue quotes it); its other rows are not
reproduced here. Writes bench/results/paper.md and paper.png.
"""

from __future__ import annotations

import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import RESULTS, SCENES, save_figure, write_text  # noqa: E402

STAGES = (("after_phase1", "phase 1"), ("after_phase2", "phase 2"),
          ("after_extra", "extra passes"), (None, "certified"))


def _stage(run: dict, key: str | None) -> dict:
    m = run["metrics"]
    return m if key is None else (m.get(key) or {})


def rows() -> list[dict]:
    out = []
    for name, spec in SCENES.items():
        f = RESULTS / f"{name}.json"
        if not f.exists():
            continue
        s = json.loads(f.read_text())
        row = {"scene": name, "paper": spec.get("paper"), "stages": {}}
        for key, label in STAGES:
            vals = [_stage(r, key) for r in s["runs"]]
            if not all(vals):
                continue
            row["stages"][label] = {
                "tvd": statistics.median(v["tvd"] for v in vals),
                "nni": statistics.median((v.get("nni_mean") or 0.0) for v in vals),
                "count": statistics.median(v["count"] for v in vals),
                "density": statistics.median(v["density"] for v in vals)}
        row.update(objects=s["median_count"], seconds=s["median_seconds"],
                   density=s["median_density"], seeds=s["seeds"])
        out.append(row)
    return out


def write(rs: list[dict], path: Path) -> None:
    lines = ["# Our results beside the paper's tables", "",
             "Medians over the seeds of `python bench/run.py --part scenes` (2-core "
             "machine). The paper's figures are given where this workspace has them "
             "(polyhedra-80, quoted by the engine issue); \"n/a\": not available here.", "",
             "## Table 1: type mix (TVD, lower is better) and clumping (NNI, > 1 regular)",
             "", "| scene | " + " | ".join(f"TVD {lb} | NNI {lb}" for _, lb in STAGES) + " |",
             "|---|" + "---|---|" * len(STAGES)]
    for r in rs:
        cells = []
        for _, label in STAGES:
            st = r["stages"].get(label)
            cells += [f"{st['tvd']:.3f}", f"{st['nni']:.2f}"] if st else ["", ""]
        lines.append(f"| {r['scene']} | " + " | ".join(cells) + " |")
    lines += ["", "The paper's Table 1 values: n/a.", "",
              "## Table 2: objects, time, density", "",
              "| scene | objects (ours) | time (s, ours, 2 cores) | density (ours) | "
              "objects (paper) | time (s, paper, 12 cores) | density (paper) |",
              "|---|---|---|---|---|---|---|"]
    for r in rs:
        p = r["paper"]
        theirs = (f"{p['objects']} | {p['seconds']:.0f} | {p['density']:.1%}" if p
                  else "n/a | n/a | n/a")
        lines.append(f"| {r['scene']} | {r['objects']:.0f} | {r['seconds']:.0f} | "
                     f"{r['density']:.1%} | {theirs} |")
    write_text(path, "\n".join(lines) + "\n")


def chart(rs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 4.5))
    labels = [lb for _, lb in STAGES]
    width = 0.8 / max(len(rs), 1)
    for i, r in enumerate(rs):
        xs = [j + i * width for j in range(len(labels))]
        a1.bar(xs, [r["stages"].get(lb, {}).get("tvd", 0) for lb in labels], width,
               label=r["scene"])
        a2.bar(xs, [r["stages"].get(lb, {}).get("nni", 0) for lb in labels], width,
               label=r["scene"])
    for ax, title in ((a1, "TVD by stage (lower is better)"),
                      (a2, "NNI by stage (> 1: no clumps)")):
        ax.set_xticks([j + 0.4 - width / 2 for j in range(len(labels))], labels)
        ax.set_title(title, fontsize=10)
        ax.legend(fontsize=7)
    a2.axhline(1.0, color="k", lw=0.8, ls=":")
    for r in rs:
        a3.scatter(r["seconds"], 100 * r["density"], label=f"{r['scene']} (ours)")
        if r["paper"]:
            p = r["paper"]
            a3.scatter(p["seconds"], 100 * p["density"], marker="x", s=80,
                       label=f"{r['scene']} (paper, 12 cores)")
    a3.set_xlabel("time (s)")
    a3.set_ylabel("density (%)")
    a3.set_title("Table 2: density against time", fontsize=10)
    a3.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    rs = rows()
    if not rs:
        print("no scene results in bench/results yet: run bench/run.py --part scenes")
        return 0
    write(rs, RESULTS / "paper.md")
    chart(rs, RESULTS / "paper.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
