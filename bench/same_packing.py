"""Do two versions of the engine pack the same? Placements of fixed scenes, compared to 1e-9.

Packs every bench scene (`scenes.SCENES`) with its time budget removed (so the packing
depends on the inputs and the seed alone) and the bundled default scene, and writes each
scene's placements (type, quaternion w,x,y,z, translation in the container frame) to JSON.
With --compare REF.json it compares the new placements with REF's and exits 1 on any
difference above --tol (container units; quaternions are compared up to sign).

    python bench/same_packing.py -o before.json            # on the old commit
    python bench/same_packing.py --compare before.json     # on the new one

Uses only `pack()`'s keyword arguments, so it runs unchanged across refactors.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scenes import MESHES, SCENES, write_json  # noqa: E402


def default_scene() -> tuple[str, list[str], dict]:
    from importlib import resources

    folder = resources.files("jampacked.core").joinpath("data", "default_scene")
    fruit = ["011_banana", "012_strawberry", "014_lemon", "015_peach", "017_orange"]
    return (str(folder.joinpath("spot.obj")), [str(folder.joinpath(f + ".obj")) for f in fruit],
            {"container_size": 150.0, "type_scale": 300.0})  # as `jampacked pack default`


def pack_scene(name: str, seed: int) -> dict:
    from jampacked.core.api import pack

    if name == "default":
        container, types, kwargs = default_scene()
    else:
        sc = SCENES[name]
        container = sc["container"]
        if not container.startswith("box:"):
            container = str(MESHES / container)
        types = [str(MESHES / t) for t in sc["types"]]
        kwargs = {k: v for k, v in sc["kwargs"].items() if k != "time_budget"}
    t0 = time.perf_counter()
    p = pack(container, types, seed=seed, **kwargs)
    return {"seconds": time.perf_counter() - t0, "type_index": p.type_index.tolist(),
            "rotations": p.rotations.tolist(), "translations": p.translations.tolist(),
            "density": float(p.metrics["density"])}


def differences(ref: dict, new: dict, tol: float) -> list[str]:
    """What differs between two scenes' placements (empty: the same to `tol`)."""
    if ref["type_index"] != new["type_index"]:
        return [f"objects or types differ: {len(ref['type_index'])} -> "
                f"{len(new['type_index'])} objects"]
    out = []
    dt = np.abs(np.array(ref["translations"]) - np.array(new["translations"])).max(initial=0)
    qa, qb = np.array(ref["rotations"]), np.array(new["rotations"])
    dq = np.minimum(np.abs(qa - qb).max(axis=1, initial=0),
                    np.abs(qa + qb).max(axis=1, initial=0)).max(initial=0)
    if dt > tol:
        out.append(f"translations differ by up to {dt:.3g}")
    if dq > tol:
        out.append(f"rotations differ by up to {dq:.3g}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", type=Path)
    ap.add_argument("--compare", type=Path, help="reference JSON from an earlier run")
    ap.add_argument("--scenes", nargs="*", default=["default", *SCENES])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tol", type=float, default=1e-9)
    args = ap.parse_args(argv)
    ref = json.loads(args.compare.read_text()) if args.compare else None
    result, bad = {}, 0
    for name in args.scenes:
        rec = pack_scene(name, args.seed)
        result[name] = rec
        line = f"{name}: {len(rec['type_index'])} objects, {rec['density']:.2%}, " \
               f"{rec['seconds']:.1f} s"
        if ref is not None and name in ref:
            diff = differences(ref[name], rec, args.tol)
            bad += bool(diff)
            line += "  " + ("; ".join(diff) if diff else "same placements")
        print(line, flush=True)
    if args.output:
        write_json(args.output, {"seed": args.seed, **result})
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
