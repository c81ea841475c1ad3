"""Accuracy and time of the container shell: measured wall thickness against T.

    python bench/shell_accuracy.py                  # Spot, torus, knight at T = 1, 2, 4 mm
    python bench/shell_accuracy.py --alternatives   # also time manifold3d's level_set and
                                                    # minkowski_difference on Spot at T = 2

Each container is scaled to 150 mm largest extent. The wall thickness is the exact distance
from points spread uniformly over the inner surface to the container mesh (10000 points).
Writes bench/results/shell_accuracy.json and prints a table. Timings are wall-clock seconds
on this machine (2 cores, shared, noisy); numba caches are warm after the first row.
Meshes come from ../shared/meshes (beside the checkout), or --meshes DIR.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import manifold3d as m3
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"
SIZE = 150.0
CONTAINERS = ("spot", "torus", "knight")
THICKNESSES = (1.0, 2.0, 4.0)


def load(meshes: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Container `name` from meshes/containers, scaled to SIZE mm largest extent."""
    from jampacked.core.meshes import load_mesh

    mesh = load_mesh(meshes / "containers" / f"{name}.obj", role="container")
    return mesh.vertices * (SIZE / mesh.extents.max()), np.asarray(mesh.faces)


def thickness_stats(vertices: np.ndarray, faces: np.ndarray, inner: m3.Manifold) -> dict:
    """Percentiles of the wall thickness over 10000 points of the inner surface."""
    from jampacked.export.shell import measure_wall_thickness

    d = measure_wall_thickness(vertices, faces, inner, n=10000, seed=1)
    p = np.percentile(d, [0, 1, 50, 99, 100])
    return {"min": p[0], "p1": p[1], "median": p[2], "p99": p[3], "max": p[4]}


def run_shell(name: str, vertices: np.ndarray, faces: np.ndarray, thickness: float) -> dict:
    """One row: make_shell, then validate the result and measure it densely."""
    from jampacked.export.shell import make_shell
    from jampacked.export.validate import validate_arrays

    shell, report = make_shell(vertices, faces, thickness)
    cavities = [p for p in shell.decompose() if p.volume() < 0]
    stats = thickness_stats(vertices, faces, m3.Manifold.compose(cavities))
    mesh = shell.to_mesh()
    t = time.perf_counter()
    val = validate_arrays(np.asarray(mesh.vert_properties)[:, :3], mesh.tri_verts)
    return {
        "method": "grid + marching tetrahedra (make_shell)", "container": name,
        "size_mm": SIZE, "T": thickness, "seconds": round(report.seconds, 3),
        "grid_spacing": round(report.grid_spacing, 4), "tolerance": round(report.tolerance, 4),
        "triangles": report.triangles, "container_triangles": len(faces),
        "cavities": report.cavities, "volume": round(report.volume, 2),
        "thickness": {k: round(float(v), 4) for k, v in stats.items()},
        "relative_error": {"min": round(stats["min"] / thickness - 1, 4),
                           "median": round(stats["median"] / thickness - 1, 4),
                           "max": round(stats["max"] / thickness - 1, 4)},
        "validated": bool(val.passed), "validate_seconds": round(time.perf_counter() - t, 3),
    }


def run_level_set(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                  spacing: float) -> dict:
    """manifold3d level_set over the same distance grid, read by a Python callback."""
    from jampacked.export.offset import offset_grid

    values, origin = offset_grid(np.ascontiguousarray(vertices, np.float64),
                                 np.ascontiguousarray(faces, np.int64), thickness, spacing)
    flat = values.ravel().tolist()
    nx, ny, nz = values.shape
    ox, oy, oz = origin.tolist()
    inv = 1.0 / spacing
    far = float(values.min())
    calls = [0]

    def sdf(x: float, y: float, z: float) -> float:  # trilinear interpolation
        calls[0] += 1
        fx, fy, fz = (x - ox) * inv, (y - oy) * inv, (z - oz) * inv
        i, j, k = int(fx), int(fy), int(fz)
        if i < 0 or j < 0 or k < 0 or i >= nx - 1 or j >= ny - 1 or k >= nz - 1:
            return far
        u, w, t = fx - i, fy - j, fz - k
        b = (i * ny + j) * nz + k
        b2 = b + ny * nz
        c00 = flat[b] + (flat[b + 1] - flat[b]) * t
        c01 = flat[b + nz] + (flat[b + nz + 1] - flat[b + nz]) * t
        c10 = flat[b2] + (flat[b2 + 1] - flat[b2]) * t
        c11 = flat[b2 + nz] + (flat[b2 + nz + 1] - flat[b2 + nz]) * t
        c0 = c00 + (c01 - c00) * w
        c1 = c10 + (c11 - c10) * w
        return c0 + (c1 - c0) * u

    lo, hi = vertices.min(axis=0) - spacing, vertices.max(axis=0) + spacing
    t0 = time.perf_counter()
    inner = m3.Manifold.level_set(sdf, [*lo, *hi], spacing, thickness)
    seconds = time.perf_counter() - t0
    stats = thickness_stats(vertices, faces, inner)
    return {"method": f"manifold3d level_set, Python trilinear callback, edge {spacing:g}",
            "container": "spot", "T": thickness, "seconds_level_set_only": round(seconds, 3),
            "sdf_calls": calls[0], "inner_triangles": inner.num_tri(),
            "thickness": {k: round(float(v), 4) for k, v in stats.items()}}


def run_minkowski(vertices: np.ndarray, faces: np.ndarray, thickness: float,
                  segments: int) -> dict:
    """manifold3d minkowski_difference of the container and a polygonal sphere."""
    from jampacked.core.solids import to_solid

    outer = to_solid(vertices, faces)
    ball = m3.Manifold.sphere(thickness, segments)
    t0 = time.perf_counter()
    inner = outer.minkowski_difference(ball)
    inner.num_tri()
    seconds = time.perf_counter() - t0
    stats = thickness_stats(vertices, faces, inner)
    return {"method": f"manifold3d minkowski_difference, sphere of {ball.num_tri()} triangles",
            "container": "spot", "T": thickness, "seconds": round(seconds, 3),
            "inner_triangles": inner.num_tri(),
            "thickness": {k: round(float(v), 4) for k, v in stats.items()}}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=ROOT.parent / "shared" / "meshes")
    parser.add_argument("--containers", nargs="+", default=list(CONTAINERS))
    parser.add_argument("--thickness", nargs="+", type=float, default=list(THICKNESSES))
    parser.add_argument("--alternatives", action="store_true",
                        help="also time level_set and minkowski_difference on spot, T = 2")
    parser.add_argument("--out", type=Path, default=RESULTS / "shell_accuracy.json")
    args = parser.parse_args(argv)

    rows = []
    print(f"{'container':10} {'T':>4} {'grid':>6} {'min':>7} {'p1':>7} {'median':>7} "
          f"{'p99':>7} {'max':>7} {'tris':>7} {'s':>6} valid")
    for name in args.containers:
        vertices, faces = load(args.meshes, name)
        for thickness in args.thickness:
            row = run_shell(name, vertices, faces, thickness)
            rows.append(row)
            th = row["thickness"]
            print(f"{name:10} {thickness:4g} {row['grid_spacing']:6.3f} {th['min']:7.3f} "
                  f"{th['p1']:7.3f} {th['median']:7.3f} {th['p99']:7.3f} {th['max']:7.3f} "
                  f"{row['triangles']:7d} {row['seconds']:6.2f} {row['validated']}",
                  flush=True)
    alternatives = []
    if args.alternatives:
        vertices, faces = load(args.meshes, "spot")
        for spacing in (1.0,):
            alternatives.append(run_level_set(vertices, faces, 2.0, spacing))
            print(alternatives[-1], flush=True)
        for segments in (8, 16):
            alternatives.append(run_minkowski(vertices, faces, 2.0, segments))
            print(alternatives[-1], flush=True)
    out = {
        "format": "jampacked.bench.shell_accuracy", "version": 1,
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform(),
                    "python": sys.version.split()[0]},
        "notes": "thickness: exact distance from 10000 points on the inner surface to the "
                 "container mesh, container units (mm); container scaled to 150 mm.",
        "rows": rows,
        "alternatives": alternatives,
    }
    if args.out.exists() and not args.alternatives:  # keep earlier alternative timings
        try:
            previous = json.loads(args.out.read_text())
            out["alternatives"] = previous.get("alternatives", [])
        except (OSError, ValueError):
            pass
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
