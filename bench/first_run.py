"""The first run: a pack and a validation with numba's cache empty (cold) and filled (warm).

    python bench/first_run.py [--budget 5]

Each run is its own process, with NUMBA_CACHE_DIR and JAMPACKED_CACHE (the approximation
cache) in a fresh temporary folder: the cold run compiles every kernel it calls, the warm
run after it loads them from that folder. The pack is `jampacked pack default
--time-budget B` (the bundled scene); the validation `jampacked validate` of the bundled
Spot mesh (in its own empty cache, so it compiles the export's kernels alone). Records wall
times and the pack's own stage times (load, approximate, compile = the kernels ready before
the budget starts) in bench/results/first_run.json. Times are wall-clock seconds on
whatever else runs on the machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "bench" / "results" / "first_run.json"


def _jampacked() -> list[str]:
    return [sys.executable, "-m", "jampacked.cli.main"]


def _run(argv: list[str], cache: Path) -> tuple[float, subprocess.CompletedProcess]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache / "numba"),
           "JAMPACKED_CACHE": str(cache / "approximations")}
    t0 = time.perf_counter()
    done = subprocess.run(argv, env=env, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({done.returncode}):\n{done.stderr}")
    return seconds, done


def pack_runs(budget: float, folder: Path) -> dict:
    """Cold then warm `jampacked pack default`: wall time and the packing's stage times."""
    cache = folder / "pack-cache"
    runs = {}
    for case in ("cold", "warm"):
        out = folder / f"packing-{case}.json"
        seconds, done = _run([*_jampacked(), "pack", "default", "--time-budget", str(budget),
                              "-o", str(out), "-q"], cache)
        packing = json.loads(out.read_text())
        runs[case] = {"wall_s": round(seconds, 2),
                      "timings_s": {k: round(v, 2) for k, v in packing["timings"].items()},
                      "objects": len(packing["placements"]),
                      "stderr": done.stderr.strip().splitlines()[-2:]}
        print(f"pack {case}: {seconds:.1f} s, {runs[case]['timings_s']}", flush=True)
    return runs


def validate_runs(folder: Path) -> dict:
    """Cold then warm `jampacked validate` of the bundled Spot mesh."""
    from importlib import resources

    mesh = resources.files("jampacked.core").joinpath("data", "default_scene", "spot.obj")
    cache = folder / "validate-cache"
    runs = {}
    for case in ("cold", "warm"):
        seconds, _ = _run([*_jampacked(), "validate", str(mesh)], cache)
        runs[case] = {"wall_s": round(seconds, 2)}
        print(f"validate {case}: {seconds:.1f} s", flush=True)
    return runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--budget", type=float, default=5.0, help="pack time budget (s)")
    ap.add_argument("-o", "--output", type=Path, default=OUT)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="jampacked-first-run-") as tmp:
        folder = Path(tmp)
        result = {"machine": f"{platform.machine()}, {os.cpu_count()} cores",
                  "python": platform.python_version(), "budget_s": args.budget,
                  "pack": pack_runs(args.budget, folder), "validate": validate_runs(folder)}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
