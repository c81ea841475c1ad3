"""Where density is lost: the packed fraction against depth from the container wall.

    python bench/density_profile.py                    # packs fruit-in-bunny, seed 1
    python bench/density_profile.py --packing P.json   # any packing file instead

Without --packing it packs the scene (its bench settings) and keeps the packing as
bench/results/packing-<scene>-seed<N>.json.

Samples points uniformly in the container (seeded), bins them by their depth from the wall
(container grid, trilinear) in units of the types' mean equivalent radius r, and counts
those inside a placed object (each type's signed distance grid at about r/40, in the
object's frame). The estimate's overall fraction is printed beside the packing's exact
density as a check. For reference it draws the fraction a hexagonal layer of touching
spheres of radius r fills against a flat wall, in the band 0-r (60.5% over the band), and
how dense that band would have to be, the rest unchanged, for the density to reach
--target (issue 5's bar for fruit-in-bunny: 55%). Writes
bench/results/density_profile.json and density_profile.png; for a --packing of one's own,
PACKING-profile.json and .png beside it (the bench's record is kept), or --out.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import MESHES, RESULTS, SCENES, save_figure, write_json  # noqa: E402

#: depth bin edges, in mean equivalent radii
EDGES = (0.0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 4.0, np.inf)
SAMPLES = 400_000


def hex_layer_fraction(z: np.ndarray, r: float) -> np.ndarray:
    """Fraction of the plane at depth z (0 <= z <= 2r) that a hexagonal layer of touching
    spheres of radius r, resting on a flat wall, covers: pi (r^2 - (z-r)^2) / (2 sqrt3 r^2)."""
    z = np.clip(np.asarray(z, float), 0.0, 2 * r)
    return np.pi * (r * r - (z - r) ** 2) / (2 * np.sqrt(3) * r * r)


def profile(packing_path: Path, target: float = 0.55, samples: int = SAMPLES,
            seed: int = 0) -> dict:
    """The packed fraction per depth band of a packing file (see the module doc)."""
    from jampacked.core.container import build_container
    from jampacked.core.distance import distance_grid
    from jampacked.core.kernels import sample_grid_many
    from jampacked.core.meshes import load_mesh
    from jampacked.core.metrics import equivalent_radius
    from jampacked.core.packing import container_mesh
    from jampacked.core.packing_json import load_packing

    p = load_packing(packing_path)
    cm = container_mesh(p)
    cv = cm.vertices @ p.frame_from_file[:3, :3].T + p.frame_from_file[:3, 3]
    volumes = np.array([t.volume for t in p.types])
    shares = np.array([t.share for t in p.types])
    r = float(np.sum(shares * equivalent_radius(volumes)))
    cont = build_container(cv, cm.faces, p.container_volume, r / 20)
    g = cont.grid
    rng = np.random.default_rng(seed)
    lo, hi = cv.min(axis=0), cv.max(axis=0)
    pts = lo + rng.random((samples, 3)) * (hi - lo)
    depth = sample_grid_many(g.values, g.origin, g.spacing, pts)
    inside = depth > 0
    pts, depth = pts[inside], depth[inside]
    occupied = np.zeros(len(pts), bool)
    grids = []
    for t in p.types:
        m = load_mesh(t.path, role="object")
        v = m.vertices @ t.local_from_file[:3, :3].T + t.local_from_file[:3, 3]
        reach = float(np.linalg.norm(v, axis=1).max())
        grids.append((distance_grid(v, m.faces, r / 40, pad=r / 20, band=4), reach))
    mats = p.matrices()
    for k in range(p.n):
        grid, reach = grids[p.type_index[k]]
        m = mats[k]
        near = np.flatnonzero(~occupied & (np.sum((pts - m[:3, 3]) ** 2, axis=1)
                                           < (reach * p.scales[k]) ** 2))
        if len(near) == 0:
            continue
        local = (pts[near] - m[:3, 3]) @ m[:3, :3] / p.scales[k] ** 2  # R^T (x - t) / s
        occupied[near] = sample_grid_many(grid.values, grid.origin, grid.spacing,
                                          np.ascontiguousarray(local)) > 0
    d = depth / r
    bands = []
    for a, b in zip(EDGES[:-1], EDGES[1:], strict=True):
        sel = (d >= a) & (d < b)
        bands.append({"from_r": a, "to_r": None if np.isinf(b) else b,
                      "volume_share": float(sel.mean()),
                      "density": float(occupied[sel].mean()) if sel.any() else None})
    first = d < 1.0
    ideal_first = float(np.pi / (3 * np.sqrt(3)))  # hex_layer_fraction averaged over 0..r
    needed = (target * len(d) - float(occupied[~first].sum())) / float(first.sum())
    return {
        "packing": str(packing_path), "objects": p.n, "density": p.metrics.get("density"),
        "estimate": float(occupied.mean()), "samples_inside": int(len(d)),
        "mean_equivalent_radius": r, "bands": bands,
        "first_band": {"volume_share": float(first.mean()),
                       "density": float(occupied[first].mean()),
                       "hex_layer_density": ideal_first},
        "beyond_first_band_density": float(occupied[~first].mean()),
        "target": target, "first_band_density_for_target": needed,
    }


def _pack_scene(scene: str, seed: int, meshes: Path, out: Path) -> None:
    from jampacked.core.api import pack
    from jampacked.core.packing_json import save_packing

    spec = SCENES[scene]
    container = spec["container"]
    if not container.startswith("box:"):
        container = str(meshes / container)
    t0 = time.perf_counter()
    p = pack(container, [str(meshes / t) for t in spec["types"]], seed=seed,
             **spec["kwargs"])
    print(f"{scene} seed {seed}: {p.n} objects, density {p.metrics['density']:.1%}, "
          f"{time.perf_counter() - t0:.0f} s")
    save_packing(p, out)


def chart(data: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for b in data["bands"]:
        hi = b["to_r"] if b["to_r"] is not None else b["from_r"] + 1.0
        ax.fill_between([b["from_r"], hi], 0, b["density"] or 0.0, step="pre", alpha=0.35,
                        color="tab:blue", lw=0)
        ax.plot([b["from_r"], hi], [b["density"]] * 2, color="tab:blue", lw=2)
        ax.text((b["from_r"] + hi) / 2, (b["density"] or 0) + 0.015,
                f"{b['volume_share']:.0%}", ha="center", fontsize=7, color="tab:blue")
    z = np.linspace(0, 1, 100)
    ax.plot(z, hex_layer_fraction(z, 1.0), color="tab:orange", lw=1.5,
            label="hexagonal layer of spheres on a flat wall (first layer)")
    ax.axhline(data["density"], color="k", ls=":", lw=1,
               label=f"certified density {data['density']:.1%}")
    ax.set_xlabel("depth from the container wall (mean equivalent radii r = "
                  f"{data['mean_equivalent_radius']:.3g})")
    ax.set_ylabel("packed fraction")
    ax.set_ylim(0, 1)
    ax.set_xlim(0, EDGES[-2] + 1)
    ax.set_title(f"{Path(data['packing']).stem}: {data['objects']} objects; bands labelled "
                 "with their share of the volume", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    fig.tight_layout()
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--packing", type=Path, help="a packing file (default: pack --scene)")
    ap.add_argument("--scene", default="fruit-in-bunny", choices=sorted(SCENES))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--target", type=float, default=0.55,
                    help="density to say the first band's requirement for (default 0.55)")
    ap.add_argument("--out", type=Path,
                    help="where to write the profile's JSON (a .json name); its chart goes "
                    "beside it as .png (default: with --packing, PACKING-profile.json beside "
                    "it; else the bench's own, bench/results/density_profile.json)")
    a = ap.parse_args(argv)
    path = a.packing
    out = a.out
    if out is None:
        out = (RESULTS / "density_profile.json" if path is None
               else path.with_name(f"{path.stem}-profile.json"))
    if out.suffix.lower() != ".json":
        ap.error(f"--out {out}: the profile is JSON; give a .json name (its chart goes "
                 "beside it as .png)")
    if path is not None and out.resolve() == path.resolve():
        ap.error(f"--out {out} is the packing read; give another name")
    if path is None:
        path = RESULTS / f"packing-{a.scene}-seed{a.seed}.json"
        _pack_scene(a.scene, a.seed, a.meshes, path)
    data = profile(path, a.target)
    data["packing"] = path.name if a.packing is None else str(path)
    write_json(out, data)
    chart(data, out.with_suffix(".png"))
    fb = data["first_band"]
    print(f"estimate {data['estimate']:.1%} (certified {data['density']:.1%}); band 0-r: "
          f"{fb['volume_share']:.0%} of the volume at {fb['density']:.1%} (hexagonal sphere "
          f"layer: {fb['hex_layer_density']:.1%}); beyond: "
          f"{data['beyond_first_band_density']:.1%}; {data['target']:.0%} overall needs the "
          f"band at {data['first_band_density_for_target']:.1%}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
