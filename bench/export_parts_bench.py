"""Parts export at scale: ~100 detailed YCB scans (16k triangles each, ~1.7M in all) packed
with a 0.5 mm clearance, exported with --mode parts to one 3MF and validated. Writes
bench/results/export_parts.json.

    python bench/export_parts_bench.py                    # packs the scene first if needed
    python bench/export_parts_bench.py --baseline 52ce484 # also times that commit's code
    python bench/export_parts_bench.py --regenerate       # packs the scene again
    python bench/export_parts_bench.py --baseline A --ref B  # commit A against commit B

The scene: five YCB google_16k scans (apple, lemon, pear, orange, plum; the peach scan is
self-intersecting and cannot be exported as a watertight part) x250 in an 82 mm box, seed 1,
--clearance 0.5, 150 s placement budget: about 100 objects. Packing takes ~5 minutes, so the
packing is kept (default /tmp/jampacked-bench/ycb-parts.json). Each export runs in its own
process (peak memory is that process's), after a warm-up export of three of the objects
that loads numba's cache; a baseline runs the code of a git commit (``git archive``) the same
way, in the same run, after the code measured (each run's figures are saved as it ends).
Bar (issue 21): <= 60 s. Wall-clock seconds on this 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import MESHES, RESULTS, ROOT  # noqa: E402

PACKING = Path(tempfile.gettempdir()) / "jampacked-bench" / "ycb-parts.json"
YCB = [f"fruit/ycb/{n}.ply" for n in
       ("013_apple", "014_lemon", "016_pear", "017_orange", "018_plum")]
BAR_SECONDS = 60.0


def make_packing(meshes: Path, out: Path) -> None:
    """Pack the scene (about 5 minutes) and save it to ``out``."""
    from jampacked.core.api import pack
    from jampacked.core.packing_json import save_packing

    p = pack("box:82x82x82", [str(meshes / f) for f in YCB], seed=1, time_budget=150.0,
             type_scale=250.0, clearance=0.5)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_packing(p, out)


def child(packing_path: str, out_dir: str) -> dict:
    """One timed parts export in this process, after a warm-up on three of the objects."""
    import dataclasses
    import resource

    from jampacked.core.packing_json import load_packing
    from jampacked.export.assemble import export_packing
    from jampacked.export.options import ExportOptions

    packing = load_packing(packing_path)
    small = dataclasses.replace(packing, type_index=packing.type_index[:3],
                                rotations=packing.rotations[:3],
                                translations=packing.translations[:3],
                                scales=packing.scales[:3])
    export_packing(small, Path(out_dir) / "warm.3mf", ExportOptions(mode="parts"))
    t0 = time.perf_counter()
    rep = export_packing(packing, Path(out_dir) / "parts.3mf", ExportOptions(mode="parts"))
    wall = time.perf_counter() - t0
    return {"wall": wall, "timings": rep.timings, "objects": rep.objects,
            "bodies": rep.bodies, "triangles": rep.triangles, "min_gap": rep.min_gap,
            "passed": rep.passed, "validation_seconds": rep.validation[0].seconds,
            "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}


def _run(packing: Path, pythonpath: str | None) -> dict:
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run([sys.executable, __file__, "--child", str(packing), tmp],
                             env=env, capture_output=True, text=True, cwd=tmp)
    if out.returncode:
        raise SystemExit(f"export failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _checkout(ref: str, where: Path) -> str:
    """The code of commit ``ref`` importable as jampacked.* (a PYTHONPATH entry)."""
    src = where / "src"
    src.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", ref, "core", "export", "cli"],
                             capture_output=True, check=True).stdout
    subprocess.run(["tar", "-x", "-C", str(src)], input=archive, check=True)
    (where / "jampacked").mkdir()
    for d in ("core", "export", "cli"):
        (where / "jampacked" / d).symlink_to(src / d)
    return str(where)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--packing", type=Path, default=PACKING)
    ap.add_argument("--regenerate", action="store_true", help="pack the scene again")
    ap.add_argument("--baseline", metavar="REF", help="also time the code of this commit")
    ap.add_argument("--ref", metavar="REF",
                    help="time the code of this commit instead of this checkout")
    ap.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(*args.child)))
        return 0

    if args.regenerate or not args.packing.exists():
        print(f"packing the scene -> {args.packing} (about 5 minutes)")
        make_packing(args.meshes, args.packing)
    load = os.getloadavg()
    record: dict = {"scene": "ycb-16k-x250-box82-clearance0.5", "packing": str(args.packing),
                    "bar_seconds": BAR_SECONDS, "load_before": load, "runs": {}}
    runs = [(f"commit {args.ref}", args.ref)] if args.ref else [(None, None)]
    if args.baseline:  # after the code measured, so that its figure comes first
        runs.append((f"baseline {args.baseline}", args.baseline))
    for name, ref in runs:
        if ref is None:
            head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                                  capture_output=True, text=True).stdout.strip()
            record["runs"][f"this checkout ({head})"] = _run(args.packing, None)
        else:
            with tempfile.TemporaryDirectory() as tmp:
                record["runs"][name] = _run(args.packing, _checkout(ref, Path(tmp)))
        record["load_after"] = os.getloadavg()
        # written after each run: a baseline can take half an hour on a busy machine
        (RESULTS / "export_parts.json").write_text(json.dumps(record, indent=1))
    for name, r in record["runs"].items():
        print(f"{name}: {r['wall']:.1f} s ({r['objects']} objects, {r['triangles']:,} "
              f"triangles; assemble {r['timings']['assemble']:.1f} s, write+validate "
              f"{r['timings']['write_validate']:.1f} s; peak "
              f"{r['peak_rss_bytes'] / 2**30:.2f} GiB; smallest gap {r['min_gap']:.4g}; "
              f"valid {r['passed']})")
    print(f"load {load[0]:.1f} before, {record['load_after'][0]:.1f} after")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
