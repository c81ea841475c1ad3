"""Stability map: where the packing engine struggles, and how each run ends.

    python bench/stability.py            # every case, about 10-15 minutes on 2 cores
    python bench/stability.py --quick    # tiny budgets, a couple of minutes (no many-100k)
    python bench/stability.py --case clearance-0.5 --case banana-only

Each case runs `pack()` in its own process under a wall-clock timeout and ends as one of
- "certified": pack() returned and every independent check below passed;
- "clear error": pack() raised a JampackedError (its message is recorded);
- "invalid": pack() returned, but a check failed (which ones are listed);
- "crash": the process died or raised anything else (exit code and stderr tail recorded);
- "hang": the process outlived its timeout and was killed.
Each case also states the outcome the product promises ("expect"). "problems" lists what
ended otherwise: an unexpected outcome, no objects (or a type with a share never placed)
without an error or a stop, placement running well past its time budget.

Independent checks of a returned packing (not the engine's own code): every placement
number and metric finite, unit quaternions, scale 1, every object centre inside the
container (generalised winding number of the container mesh, read by trimesh, in the
container frame), the certificate certified with worst overlap and outside volume <= its
tolerance (and gaps >= the clearance), density and TVD recomputed from the mesh files with
trimesh.

Sweeps: thin container features (knight, hand, armadillo at sizes where fruit fit the body
but not the fingers or ears; "unreachable" is the share of the container that a ball of the
thinnest fruit's inscribed radius cannot reach), clearance, size ratio of two types, an
elongated type alone, objects larger than the container, 5000 and 100000 small objects under
a time budget, extreme shares, one type. Writes bench/results/stability.json, stability.md
and stability.png (atomically; --report-only redraws the last two from the JSON); --quick
writes stability-quick.* instead.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from scenes import FRUIT, MESHES, RESULTS, save_figure, write_text  # noqa: E402
from scenes import write_json as _write_json  # noqa: E402

LEMON = "fruit/ycb_lowpoly/014_lemon.obj"
ORANGE = "fruit/ycb_lowpoly/017_orange.obj"
STRAWBERRY = "fruit/ycb_lowpoly/012_strawberry.obj"
BANANA = "fruit/ycb_lowpoly/011_banana.obj"
#: equivalent radius of the strawberry / the orange (both x1): a 1:r size ratio scales the
#: strawberry by (1 / r) / this, so that f(V_orange) / f(V_strawberry) = r
_STRAWBERRY_OVER_ORANGE = (48.0e-6 / 202.0e-6) ** (1 / 3)

OUTCOMES = ("certified", "clear error", "invalid", "crash", "hang")


def _case(name: str, sweep: str, param: str, value, container: str, types: list,
          budget: float, *, expect: str = "certified", shares=None, thin: bool = False,
          timeout: float | None = None, **kwargs) -> dict:
    """One case. types: mesh paths (under --meshes) or (path, extra scale) pairs; the extra
    scale multiplies that type on top of type_scale. budget: pack's time_budget (s)."""
    return {"name": name, "sweep": sweep, "param": param, "value": value,
            "container": container,
            "types": [list(t) if isinstance(t, tuple) else [t, 1.0] for t in types],
            "shares": shares, "kwargs": {"seed": 1, "time_budget": budget, **kwargs},
            "expect": expect, "thin": thin,
            # placement is bounded by the budget; loading, compiling, certifying and the
            # independent checks come on top
            "timeout": timeout if timeout is not None else budget + 150.0}


def cases(quick: bool = False) -> list[dict]:
    """The map's cases; quick: the same cases with budgets of a few seconds."""
    def b(full: float, short: float = 2.0) -> float:
        return short if quick else full

    fruit300 = {"type_scale": 300.0}
    two = [LEMON, ORANGE]
    out = [
        # thin features: fruit (x300: 13-22 mm) fit the body, not the fingers or ears
        _case("thin-knight", "thin features", "container", "knight 150 mm",
              "containers/knight.obj", FRUIT, b(40), thin=True, container_size=150.0,
              **fruit300),
        _case("thin-hand", "thin features", "container", "hand 220 mm",
              "containers/hand.obj", FRUIT, b(40), thin=True, container_size=220.0,
              **fruit300),
        _case("thin-armadillo", "thin features", "container", "armadillo 200 mm",
              "containers/armadillo.obj", FRUIT, b(40), thin=True, container_size=200.0,
              **fruit300),
    ]
    # clearance (mm) in an 80 mm box, lemon + orange x300 (f = 8.5 and 10.9 mm); 32: no
    # object fits but the up-front depth check passes; 40: the depth check refuses
    for c, expect in ((0.0, "certified"), (0.5, "certified"), (2.0, "certified"),
                      (5.0, "certified"), (32.0, "clear error"), (40.0, "clear error")):
        out.append(_case(f"clearance-{c:g}", "clearance", "clearance (mm)", c, "box:80x80x80",
                         two, b(20), expect=expect, clearance=c, **fruit300))
    # size ratio: orange x300 with a strawberry scaled so the equivalent radii differ 1:r
    for r in (1, 5, 10, 20):
        small = (STRAWBERRY, 1.0 / r / _STRAWBERRY_OVER_ORANGE)
        out.append(_case(f"size-ratio-1:{r}", "size ratio", "size ratio", f"1:{r}",
                         "box:80x80x80", [ORANGE, small], b(30), **fruit300))
    out += [
        _case("banana-only", "elongated", "type", "banana x300 (110 x 54 x 11 mm)",
              "containers/bunny.obj", [BANANA], b(30), container_size=150.0, **fruit300),
        _case("too-large-all", "too large", "objects", "fruit x300 in a 30 mm bunny",
              "containers/bunny.obj", FRUIT, b(20), expect="clear error",
              container_size=30.0, **fruit300),
        # one type fits nowhere: the mix cannot be kept, which must be said, not dropped
        _case("too-large-one", "too large", "objects",
              "orange 29 mm + strawberry 7 mm, 22 mm box", "box:22x22x22",
              [(ORANGE, 4 / 3), (STRAWBERRY, 0.5)], b(20), expect="clear error",
              **fruit300),
        _case("many-5000", "many objects", "expected objects", "~5000 (x110 in 100 mm box)",
              "box:100x100x100", [STRAWBERRY, LEMON], b(60, 5.0), type_scale=110.0,
              timeout=b(60, 5.0) + 400.0),
    ]
    if not quick:  # beyond the range: 100,000 expected objects, far more than 10 s can place
        out.append(_case("many-100k", "many objects", "expected objects",
                         "~100000 (x40 in 100 mm box)", "box:100x100x100", [STRAWBERRY, LEMON],
                         10.0, type_scale=40.0, timeout=400.0))
    out += [
        _case("shares-99/1", "shares", "shares", "99/1", "box:80x80x80", two, b(20),
              shares=[0.99, 0.01], **fruit300),
        _case("one-type", "shares", "types", "orange only", "box:80x80x80", [ORANGE], b(20),
              **fruit300),
    ]
    return out


# ------------------------------------------------------------------------------------------
# child process: one case


def _load_types(case: dict, meshes: Path):
    from jampacked.core.meshes import load_mesh, mesh_from_arrays

    out = []
    for path, extra in case["types"]:
        full = str(meshes / path)
        if extra == 1.0:
            out.append(full)
        else:
            m = load_mesh(full)
            out.append(mesh_from_arrays(m.vertices * extra, m.faces,
                                        name=f"{Path(path).stem} x{extra:.3g}"))
    return out


def _container_trimesh(spec: str, meshes: Path, frame):
    """The container as trimesh builds it from the file (or box spec), in the container
    frame (frame: the packing's 4x4 frame_from_file)."""
    import numpy as np
    import trimesh

    from jampacked.core.meshes import parse_box_spec

    box = parse_box_spec(spec)
    if box is not None:
        m = trimesh.creation.box(extents=box)
    else:
        m = trimesh.load(str(meshes / spec), force="mesh", process=True)
    frame = np.asarray(frame, float)
    v = np.asarray(m.vertices) @ frame[:3, :3].T + frame[:3, 3]
    return trimesh.Trimesh(v, m.faces, process=False)


def _unreachable(cmesh, type_arrays: list, type_scale: float) -> dict:
    """Share of the container a ball of the thinnest type's inscribed radius cannot reach
    (the container's morphological opening by that ball), from signed distance grids.
    type_arrays: (vertices, faces) per type in file units; container units out."""
    import numpy as np
    from scipy import ndimage

    from jampacked.core.distance import distance_grid

    r_in = []
    for v, f in type_arrays:
        v = np.asarray(v, float) * type_scale
        r_in.append(float(distance_grid(v, np.asarray(f), float(np.ptp(v, axis=0).max()) / 40)
                          .values.max()))
    r = min(r_in)
    spacing = float(cmesh.extents.max()) / 120
    g = distance_grid(np.asarray(cmesh.vertices), np.asarray(cmesh.faces), spacing,
                      pad=2 * spacing, band=4)
    inside = g.values > 0
    reach = ndimage.distance_transform_edt(g.values < r, sampling=spacing) <= r
    return {"inscribed_radius": r,
            "unreachable": float((inside & ~reach).sum() / max(int(inside.sum()), 1))}


def _mesh_arrays(path: str):
    import trimesh

    m = trimesh.load(path, force="mesh", process=True)
    return m.vertices, m.faces


def run_case(case: dict, meshes: Path) -> dict:
    """Pack one case in this process; returns its record (outcome certified/invalid/clear
    error). Anything but a JampackedError propagates (the parent records a crash)."""
    from jampacked.core.api import pack
    from jampacked.core.errors import JampackedError

    rec: dict = {"name": case["name"]}
    container = case["container"]
    if container == "__hang__":  # the runner's own tests
        time.sleep(3600)
    if container == "__crash__":
        raise RuntimeError("deliberate crash")
    types = _load_types(case, meshes)
    names = [Path(path).stem + ("" if extra == 1.0 else f" x{extra:.3g}")
             for path, extra in case["types"]]
    t0 = time.perf_counter()
    try:
        p = pack(container if container.startswith("box:") else str(meshes / container),
                 types, case["shares"], names=names, **case["kwargs"])
    except JampackedError as e:
        rec.update(outcome="clear error", error_type=type(e).__name__, error=str(e),
                   pack_seconds=time.perf_counter() - t0)
        return rec
    rec["pack_seconds"] = time.perf_counter() - t0
    checks, facts = check_packing(p, case, meshes, types)
    rec.update(facts)
    rec["checks"] = checks
    rec["outcome"] = "certified" if all(checks.values()) else "invalid"
    if case.get("thin"):
        cm = _container_trimesh(container, meshes, p.frame_from_file)
        arrays = [(t.vertices, t.faces) if not isinstance(t, str) else _mesh_arrays(t)
                  for t in types]
        rec["thin"] = _unreachable(cm, arrays, case["kwargs"].get("type_scale", 1.0))
    rec["maxrss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return rec


def winding_inside(vertices, faces, points, chunk: int = 64):
    """(N,) bool: points inside a closed mesh by the generalised winding number (the sum of
    the triangles' signed solid angles, Van Oosterom & Strackee), robust to the mesh's
    orientation quirks and independent of the engine's distance grids."""
    import numpy as np

    tri = np.asarray(vertices, float)[np.asarray(faces)]  # (F,3,3)
    pts = np.asarray(points, float).reshape(-1, 3)
    wn = np.zeros(len(pts))
    for s in range(0, len(pts), chunk):
        r = tri[None, :, :, :] - pts[s:s + chunk, None, None, :]  # (C,F,3,3)
        a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
        det = np.einsum("cfi,cfi->cf", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("cfi,cfi->cf", a, b) * lc
               + np.einsum("cfi,cfi->cf", b, c) * la + np.einsum("cfi,cfi->cf", c, a) * lb)
        wn[s:s + chunk] = 2.0 * np.arctan2(det, den).sum(axis=1) / (4.0 * np.pi)
    return np.abs(wn) > 0.5


def check_packing(p, case: dict, meshes: Path, types) -> tuple[dict, dict]:
    """Independent checks of a returned Packing -> (check name -> passed, facts)."""
    import numpy as np
    import trimesh

    kw = case["kwargs"]
    clearance = float(kw.get("clearance", 0.0))
    m = p.metrics
    cert = p.certificate
    n = p.n
    finite_metrics = [m["density"], m["tvd"]] + ([m["nni_mean"]] if m.get("nni_mean")
                                                  is not None else [])
    cert_numbers = [cert.get(k) for k in ("worst_overlap", "worst_outside", "min_pair_gap",
                                          "min_wall_gap") if cert.get(k) is not None]
    checks = {
        "finite": bool(np.all(np.isfinite(p.translations)) and np.all(np.isfinite(p.rotations))
                       and np.all(np.isfinite(p.scales)) and np.all(np.isfinite(finite_metrics))
                       and np.all(np.isfinite(cert_numbers))),
        "unit_rotations": bool(n == 0 or np.allclose(np.linalg.norm(p.rotations, axis=1), 1.0,
                                                     atol=1e-6)),
        "full_size": bool(np.allclose(p.scales, 1.0)),
        "certified": bool(cert["certified"] and cert["worst_overlap"] <= cert["tol"]
                          and cert["worst_outside"] <= cert["tol"]),
    }
    if clearance > 0:
        gaps = [g for g in (cert.get("min_pair_gap"), cert.get("min_wall_gap")) if g is not None]
        checks["clearance_kept"] = bool(all(g >= clearance * (1 - 1e-6) for g in gaps)
                                        and (n == 0 or cert.get("min_wall_gap") is not None))
    cm = _container_trimesh(case["container"], meshes, p.frame_from_file)
    inside = winding_inside(np.asarray(cm.vertices), np.asarray(cm.faces), p.translations)
    checks["centres_inside"] = bool(np.all(inside))
    # density and TVD from the mesh files (trimesh volumes), not the engine's numbers
    ts = float(kw.get("type_scale", 1.0))
    vols = []
    for (path, extra), _t in zip(case["types"], types, strict=True):
        tm = trimesh.load(str(meshes / path), force="mesh", process=True)
        vols.append(abs(tm.volume) * (ts * extra) ** 3)
    counts = np.bincount(p.type_index, minlength=len(vols)) if n else np.zeros(len(vols))
    dens = float(np.dot(counts, vols) / abs(cm.volume))
    q = np.asarray(case["shares"] or [1.0] * len(vols), float)
    q = q / q.sum()
    tvd = 0.5 * float(np.abs(counts / max(n, 1) - q).sum()) if n else None
    checks["density_matches"] = bool(abs(dens - m["density"]) <= 2e-3 * max(dens, 1e-9))
    if tvd is not None:
        checks["tvd_matches"] = bool(abs(tvd - m["tvd"]) <= 1e-9)
    facts = {
        "objects": int(n), "count_per_type": [int(c) for c in counts],
        "density": float(m["density"]), "density_recomputed": dens, "tvd": float(m["tvd"]),
        "nni": m.get("nni_mean"), "centres_outside": int(np.sum(~inside)),
        "stopped": p.report.stopped, "fidelity": p.report.fidelity,
        "timings": p.timings, "certificate": cert,
        "before_certification": p.report.repair.first,
        "repair": {k: v for k, v in asdict(p.report.repair).items() if k != "first"},
        "phase1": asdict(p.report.phase1), "phase2": asdict(p.report.phase2),
        "extra_passes_grown": [e.grown for e in p.report.extra_passes],
    }
    return checks, facts


def child_main(case_json: str, out: str, meshes: Path) -> int:
    rec = run_case(json.loads(case_json), meshes)
    tmp = out + ".tmp"
    Path(tmp).write_text(json.dumps(rec, default=_jsonable))
    os.replace(tmp, out)
    return 0


def _jsonable(o):
    import numpy as np

    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


# ------------------------------------------------------------------------------------------
# parent: run every case in its own process


def run_in_child(case: dict, meshes: Path, timeout: float | None = None) -> dict:
    """Run one case in a fresh process group under a wall-clock timeout; classify the end."""
    timeout = float(case["timeout"] if timeout is None else timeout)
    with tempfile.TemporaryDirectory(prefix="jp-stability-") as d:
        out = os.path.join(d, "rec.json")
        err_path = os.path.join(d, "stderr.txt")
        t0 = time.perf_counter()
        with open(err_path, "wb") as err:
            proc = subprocess.Popen(
                [sys.executable, __file__, "--child", json.dumps(case), out, "--meshes",
                 str(meshes)], stdout=subprocess.DEVNULL, stderr=err, start_new_session=True)
            try:
                rc = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                rc = None
        wall = time.perf_counter() - t0
        tail = Path(err_path).read_text(errors="replace")[-2000:]
        base = {k: case[k] for k in ("name", "sweep", "param", "value", "expect", "shares")}
        base.update(wall_seconds=wall, time_budget=case["kwargs"].get("time_budget"),
                    timeout=timeout)
        if rc is None:
            return {**base, "outcome": "hang", "stderr_tail": tail}
        if rc != 0 or not os.path.exists(out):
            return {**base, "outcome": "crash", "exit_code": rc, "stderr_tail": tail}
        rec = json.loads(Path(out).read_text())
    rec.pop("name", None)
    return {**base, **rec}


def problems(rec: dict) -> list[str]:
    """What is wrong with how a case ended (empty list: it ended as promised)."""
    out = []
    if rec["outcome"] != rec["expect"]:
        out.append(f"expected {rec['expect']}, got {rec['outcome']}")
    if rec["outcome"] == "invalid":
        out.append("failed checks: " + ", ".join(k for k, v in rec["checks"].items() if not v))
    timings = rec.get("timings") or {}
    placing = sum(v for k, v in timings.items()
                  if k not in ("load", "approximate", "certify", "total"))
    budget = rec.get("time_budget")
    if budget is not None and placing > budget + max(5.0, 0.25 * budget):
        out.append(f"placement took {placing:.0f} s for a {budget:g} s budget")
    if rec["outcome"] == "certified" and not rec.get("stopped"):
        if rec.get("objects") == 0:
            out.append("no objects placed and no error")
        elif 0 in rec.get("count_per_type", []):
            missing = [i for i, c in enumerate(rec["count_per_type"]) if c == 0
                       and (rec.get("shares") is None or rec["shares"][i] > 0)]
            if missing:
                out.append(f"type(s) {missing} never placed and no error")
    return out


def summarise(records: list[dict], quick: bool, total: float,
              load: dict | None = None) -> dict:
    """load: the 1/5/15-minute load averages at the start and end of the run."""
    by = {o: sum(r["outcome"] == o for r in records) for o in OUTCOMES}
    return {"quick": quick, "total_seconds": total, "outcomes": by,
            "cases_with_problems": [r["name"] for r in records if r["problems"]],
            "machine": f"{os.cpu_count()}-core", "load_average_1_5_15min": load,
            "records": records}


def _fmt(x, spec: str, none: str = "-") -> str:
    return none if x is None else format(x, spec)


def _load_words(summary: dict) -> str:
    load = summary.get("load_average_1_5_15min")
    if not load:  # written before the load was recorded
        return " that other benchmark jobs may have shared"
    fmt = " / ".join
    return (f" whose 1/5/15-minute load averages were {fmt(f'{x:.1f}' for x in load['start'])}"
            f" at the start and {fmt(f'{x:.1f}' for x in load['end'])} at the end")


def write_markdown(summary: dict, path: Path) -> None:
    lines = [
        "# Stability map", "",
        "Written by `python bench/stability.py" + (" --quick" if summary["quick"] else "")
        + f"` on a {summary['machine']} machine{_load_words(summary)} "
        f"({summary['total_seconds'] / 60:.1f} min in all; cases rerun with --case replace "
        "their rows). Each case runs `pack()` in its "
        "own process under a timeout. Outcomes: certified (every independent check passed), "
        "clear error (a JampackedError), invalid (a check failed), crash, hang. Time is the "
        "case's wall time (process start to end, loading and certification included); the "
        "budget bounds placement only.", "",
        "| case | swept | value | outcome | objects | density | TVD | NNI | time (s) | "
        "budget (s) | certify (s) | peak memory (MB) | stopped | problems |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in summary["records"]:
        outcome = r["outcome"]
        if outcome == "clear error":
            outcome += f": {r.get('error_type')}"
        lines.append(
            f"| {r['name']} | {r['param']} | {r['value']} | {outcome} | "
            f"{_fmt(r.get('objects'), 'd')} | {_fmt(r.get('density'), '.1%')} | "
            f"{_fmt(r.get('tvd'), '.3f')} | {_fmt(r.get('nni'), '.2f')} | "
            f"{r['wall_seconds']:.1f} | {_fmt(r.get('time_budget'), 'g')} | "
            f"{_fmt((r.get('timings') or {}).get('certify'), '.1f')} | "
            f"{_fmt(r.get('maxrss_mb'), '.0f')} | "
            f"{r.get('stopped') or '-'} | {'; '.join(r['problems']) or '-'} |")
    lines += ["", "Errors, crashes and hangs:", ""]
    for r in summary["records"]:
        if r["outcome"] == "clear error":
            lines.append(f"- {r['name']}: {r['error_type']}: {r['error']}")
        elif r["outcome"] in ("crash", "hang"):
            tail = r.get("stderr_tail", "").strip().splitlines()[-3:]
            lines.append(f"- {r['name']}: {r['outcome']} (exit {r.get('exit_code')}): "
                         + " / ".join(tail))
    thin = [r for r in summary["records"] if r.get("thin")]
    if thin:
        lines += ["", "Thin features: share of the container that a ball of the thinnest "
                  "fruit's inscribed radius cannot reach (fingers, ears, tail):", ""]
        for r in thin:
            lines.append(f"- {r['name']}: {r['thin']['unreachable']:.1%} unreachable "
                         f"(radius {r['thin']['inscribed_radius']:.1f} mm)")
    lines += ["", "![stability map](" + path.with_suffix(".png").name + ")", ""]
    write_text(path, "\n".join(lines))


COLOURS = {"certified": "#b7e1b0", "clear error": "#bcd7f0", "invalid": "#f4a6a6",
           "crash": "#e06666", "hang": "#f6c26b", "problem": "#fde9a9"}


def chart(summary: dict, path: Path) -> None:
    """Rows: cases. Columns: outcome (coloured), density bar, time bar (budget marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    recs = summary["records"]
    n = len(recs)
    fig, axes = plt.subplots(1, 3, figsize=(14, 0.36 * n + 1.6), sharey=True,
                             gridspec_kw={"width_ratios": [1.5, 1.2, 1.2]})
    y = list(range(n))[::-1]
    labels = [f"{r['name']}" for r in recs]
    ax = axes[0]
    for yy, r in zip(y, recs, strict=True):
        text = r["outcome"] + (f" ({r['objects']} obj.)" if r.get("objects") is not None
                               else "")
        if r["problems"]:
            text += "  ! " + r["problems"][-1]
        ax.barh(yy, 1.0, color=COLOURS["problem" if r["problems"] else r["outcome"]],
                edgecolor="white")
        ax.text(0.03, yy, text, va="center", fontsize=8)
    ax.set_xlim(0, 1)
    ax.set_xticks([])
    ax.set_title("outcome (! = not as promised)", fontsize=10)
    ax.set_yticks(y, labels, fontsize=8)
    ax = axes[1]
    dens = [100 * (r.get("density") or 0.0) for r in recs]
    ax.barh(y, dens, color="tab:blue")
    for yy, d, r in zip(y, dens, recs, strict=True):
        if r.get("density") is not None:
            ax.text(d + 0.5, yy, f"{d:.1f}%  TVD {r['tvd']:.2f}", va="center", fontsize=7)
    ax.set_xlabel("certified density (%), with the type mix error (TVD)")
    ax.set_xlim(0, max(dens + [10.0]) * 1.45)
    ax = axes[2]
    wall = [r["wall_seconds"] for r in recs]
    left = [0.0] * n
    parts = (("load + approximate", ("load", "approximate"), "#9ecae1"),
             ("placement", None, "#6b6b6b"), ("certify", ("certify",), "#d62728"))
    for label, keys, colour in parts:
        width = []
        for r in recs:
            t = r.get("timings") or {}
            if keys is None:  # every phase between approximation and certification
                keys_here = [k for k in t if k not in ("load", "approximate", "certify",
                                                       "total")]
            else:
                keys_here = keys
            width.append(sum(t.get(k, 0.0) for k in keys_here))
        ax.barh(y, width, left=left, color=colour, label=label)
        left = [a + b for a, b in zip(left, width, strict=True)]
    rest = [max(w - a, 0.0) for w, a in zip(wall, left, strict=True)]
    ax.barh(y, rest, left=left, color="#dddddd", label="process, imports, checks")
    budgets = [r.get("time_budget") or 0.0 for r in recs]
    ax.scatter(budgets, y, marker="|", s=160, color="black", label="placement budget",
               zorder=3)
    for yy, w in zip(y, wall, strict=True):
        ax.text(w + 0.5, yy, f"{w:.0f}", va="center", fontsize=7)
    ax.set_xlabel("wall time (s)")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.045 - 1.0 / n),
              ncol=3, frameon=False)
    for a in axes:
        a.set_ylim(-0.6, n - 0.4)
    fig.suptitle("jampacked stability map" + (" (quick)" if summary["quick"] else ""),
                 fontsize=11)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def write_json(path: Path, data) -> None:
    _write_json(path, data, default=_jsonable)


def write_outputs(summary: dict, stem: Path) -> None:
    """stem.json, stem.md and stem.png, each written atomically."""
    write_json(stem.with_suffix(".json"), summary)
    write_markdown(summary, stem.with_suffix(".md"))
    chart(summary, stem.with_suffix(".png"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="budgets of a few seconds")
    ap.add_argument("--case", action="append", help="only these cases (repeatable)")
    ap.add_argument("--meshes", type=Path, default=MESHES)
    ap.add_argument("--out", type=Path, default=RESULTS, help="folder for the results")
    ap.add_argument("--report-only", action="store_true",
                    help="rewrite the table and chart from the JSON written before, run nothing")
    ap.add_argument("--child", nargs=2, metavar=("CASE_JSON", "OUT"), help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        return child_main(a.child[0], a.child[1], a.meshes)
    stem = "stability-quick" if a.quick else "stability"
    if a.report_only:
        summary = json.loads((a.out / f"{stem}.json").read_text())
        write_outputs(summary, a.out / stem)
        return 0
    todo = cases(a.quick)
    if a.case:
        unknown = set(a.case) - {c["name"] for c in todo}
        if unknown:
            ap.error(f"unknown cases {sorted(unknown)}; known: "
                     f"{', '.join(c['name'] for c in todo)}")
        todo = [c for c in todo if c["name"] in a.case]
    a.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    load_start = list(os.getloadavg())
    records = []
    for case in todo:
        rec = run_in_child(case, a.meshes)
        rec["problems"] = problems(rec)
        records.append(rec)
        print(f"{rec['name']:>18}: {rec['outcome']:<11} objects "
              f"{_fmt(rec.get('objects'), '>4d', '   -')}  density "
              f"{_fmt(rec.get('density'), '6.1%', '     -')}  {rec['wall_seconds']:6.1f} s"
              + (f"  PROBLEM: {'; '.join(rec['problems'])}" if rec["problems"] else ""),
              flush=True)
    total = time.perf_counter() - t0
    old_file = a.out / f"{stem}.json"
    if a.case and old_file.exists():
        # a partial run replaces those cases in the last full map, keeping the others
        old = json.loads(old_file.read_text())
        new = {r["name"]: r for r in records}
        records = [new.pop(r["name"], r) for r in old["records"]] + list(new.values())
        total = old["total_seconds"]
    summary = summarise(records, a.quick, total,
                        {"start": load_start, "end": list(os.getloadavg())})
    write_outputs(summary, a.out / stem)
    print(f"{len(records)} cases in {summary['total_seconds'] / 60:.1f} min: "
          + ", ".join(f"{v} {k}" for k, v in summary["outcomes"].items() if v)
          + f"; written {a.out / stem}.json/.md/.png", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
