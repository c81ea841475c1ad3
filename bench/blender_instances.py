"""Blender benchmark: a 100,000-object result as instances, against one object per placement.

    python bench/blender_instances.py          # 100,000 instances; 5,000 and 20,000 objects
    python bench/blender_instances.py --instances 20000 --objects 2000

Runs in real Blender (the bpy wheel of the venv, headless). Placements are synthetic: the
packing of ~470 YCB low-poly fruit in the bunny (bench/results/packing-bunny-500-fruit.json),
tiled side by side until the count is reached; the fruit meshes are read from their files.
Each case goes through the add-on's own code (bridge.build_result with the settings'
Result As), then:

- ``appear_s``: build_result plus the view layer update that evaluates the modifier (what
  the viewport waits for before drawing; headless Blender draws nothing);
- ``save_s`` / ``reopen_s``: save the .blend, then open it and evaluate it again;
- ``check_s``: reading every instance back from the depsgraph after reopening (Python
  iteration, not part of what a user waits for) and comparing with the placements;
- instances only, ``make_real_1000_s``: Make Real of 1,000 selected points (it reads the
  packing JSON for exact placements).

Bar (issue 21): 100,000 objects appear in <= 15 s and the file saves and reopens. Writes
bench/results/blender_instances.json. Wall-clock seconds on this shared 2-core machine, one
run per case (load average recorded).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "tests" / "addon"))

PACKING = ROOT / "bench" / "results" / "packing-bunny-500-fruit.json"
OUT = ROOT / "bench" / "results" / "blender_instances.json"
BAR_SECONDS = 15.0


def tiled(packing, n: int):
    """``packing``'s placements repeated on a grid of container-sized cells up to n."""
    span = np.ptp(packing.translations, axis=0) * 1.1 + 1.0
    copies = -(-n // packing.n)
    side = int(np.ceil(copies ** (1 / 3)))
    cells = np.array([(i, j, k) for i in range(side) for j in range(side)
                      for k in range(side)][:copies], float)
    offsets = np.repeat(cells * span, packing.n, axis=0)[:n]
    take = np.tile(np.arange(packing.n), copies)[:n]
    return dataclasses.replace(
        packing, type_index=packing.type_index[take], rotations=packing.rotations[take],
        translations=packing.translations[take] + offsets, scales=packing.scales[take])


def _type_objects(bpy, packing) -> list[str]:
    import trimesh
    from addon_helpers import mesh_object

    names = []
    for rec in packing.types:
        m = trimesh.load(rec.path, process=False, force="mesh")
        names.append(mesh_object(bpy, rec.name, m.vertices, m.faces).name)
    return names


def _instances(bpy, points) -> list:
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return [(i.instance_object.original.name, np.array(i.matrix_world))
            for i in depsgraph.object_instances
            if i.is_instance and i.parent is not None and i.parent.original == points]


def run_case(addon, packing, n: int, kind: str, folder: Path) -> dict:
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    type_names = _type_objects(bpy, packing)
    big = tiled(packing, n)
    t = time.perf_counter()
    json_text = addon.engine.packing_to_json(big)
    json_s = time.perf_counter() - t
    request = addon.bridge.PackRequest(
        container_name="Bunny", type_names=type_names, container=None, types=[],
        shares=[r.share for r in packing.types], seed=1, clearance=0.0, fidelity="auto",
        time_budget=None, mix_tolerance=0.04, signatures=["-"])
    outcome = addon.engine.PackOutcome(packing=big, json_text=json_text)
    bpy.context.scene.jampacked.result_kind = kind
    t0 = time.perf_counter()
    coll = addon.bridge.build_result(bpy.context, request, outcome)
    t1 = time.perf_counter()
    bpy.context.view_layer.update()
    bpy.context.evaluated_depsgraph_get()
    t2 = time.perf_counter()
    path = folder / f"{kind.lower()}-{n}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    t3 = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t4 = time.perf_counter()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    bpy.context.view_layer.update()
    bpy.context.evaluated_depsgraph_get()
    t5 = time.perf_counter()
    coll = bpy.context.scene.jampacked.result
    record = {"kind": kind, "count": n, "json_s": round(json_s, 2),
              "build_s": round(t1 - t0, 2), "evaluate_s": round(t2 - t1, 2),
              "appear_s": round(t2 - t0, 2), "save_s": round(t3 - t2, 2),
              "reopen_s": round(t5 - t4, 2), "blend_mb": round(path.stat().st_size / 1e6, 1)}
    points = addon.instances.points_object(coll)
    if points is not None:
        t = time.perf_counter()
        got = _instances(bpy, points)
        record["check_s"] = round(time.perf_counter() - t, 2)
        record["instances_after_reopen"] = len(got)
        mats = big.matrices()
        sample = np.linspace(0, len(got) - 1, 200).astype(int)
        errs = []
        for name, m in (got[k] for k in sample):
            i = int(np.argmin(np.linalg.norm(big.translations - m[:3, 3], axis=1)))
            assert name == f"Jampacked {big.types[big.type_index[i]].name}", name
            errs.append(float(np.abs(m - mats[i]).max()))
        record["max_matrix_error_200_sampled"] = max(errs)
        k = min(1000, n // 2)
        select = np.zeros(n, bool)
        select[np.linspace(0, n - 1, k).astype(int)] = True
        points.data.vertices.foreach_set("select", select)
        t = time.perf_counter()
        made = addon.bridge.make_real(coll, 'SELECTED')
        record[f"make_real_{k}_s"] = round(time.perf_counter() - t, 2)
        assert len(made) == k and len(points.data.vertices) == n - k
    else:
        record["objects_after_reopen"] = len(coll.objects)
    path.unlink()
    return record


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--instances", type=int, default=100_000)
    ap.add_argument("--objects", type=int, nargs="+", default=[5_000, 20_000],
                    help="counts for the per-object path (each also as instances)")
    ap.add_argument("--output", type=Path, default=OUT)
    args = ap.parse_args(argv)

    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="jampacked-b-"))
    import bpy
    from addon_helpers import load_addon

    from jampacked.core.packing_json import load_packing

    addon = load_addon()
    # the settings only: the full register() would start compiling the engine meanwhile
    for cls in addon.props.classes:
        bpy.utils.register_class(cls)
    addon.props.register_properties()
    packing = load_packing(PACKING)
    cases = []
    try:
        with tempfile.TemporaryDirectory(prefix="jampacked-bench-") as tmp:
            runs = [(args.instances, 'INSTANCES')]
            runs += [(n, kind) for n in args.objects for kind in ('OBJECTS', 'INSTANCES')]
            for n, kind in runs:
                load = os.getloadavg()[0]
                record = run_case(addon, packing, n, kind, Path(tmp))
                record["load_1min_before"] = round(load, 2)
                print(json.dumps(record), flush=True)
                cases.append(record)
    finally:  # Blender hangs at exit while the settings' pointer polls are registered
        addon.props.unregister_properties()
        for cls in reversed(addon.props.classes):
            bpy.utils.unregister_class(cls)
    result = {"bench": "blender_instances", "blender": bpy.app.version_string,
              "source_packing": PACKING.name, "bar_appear_s": BAR_SECONDS, "cases": cases,
              "passed": cases[0]["appear_s"] <= BAR_SECONDS
              and cases[0]["instances_after_reopen"] == args.instances}
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    print(f"wrote {args.output}: 100k bar {'PASS' if result['passed'] else 'FAIL'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
