"""The add-on's bpy-free modules: worker thread, engine calls, metrics, manifest and build.

These run without Blender.
"""

from __future__ import annotations

import ast
import threading
import time
import tomllib
import zipfile
from pathlib import Path

import numpy as np
import pytest
from addon_helpers import ADDON, load_standalone

from jampacked.core.errors import InputError, MeshError
from jampacked.core.packing import Packing, TypeRecord
from jampacked.core.report import PackInputs, RunReport

worker = load_standalone("worker")
summary = load_standalone("summary")
build = load_standalone("build")


def test_thread_side_modules_never_import_bpy():
    for name in ("worker.py", "engine.py", "summary.py", "build.py", "units.py"):
        tree = ast.parse((ADDON / name).read_text(encoding="utf-8"))
        imported = {alias.name.split(".")[0] for node in ast.walk(tree)
                    if isinstance(node, ast.Import) for alias in node.names}
        imported |= {(node.module or "").split(".")[0] for node in ast.walk(tree)
                     if isinstance(node, ast.ImportFrom)}
        assert not imported & {"bpy", "mathutils", "bmesh"}, name


def _job(fn) -> object:
    job = worker.Job("Test", fn)
    job.start()
    assert job.wait(10.0)
    job.release()
    return job


def test_a_note_from_the_engine_is_kept_apart_from_the_progress_message():
    # the note (a large scene without a time budget) was the progress message until the
    # next one replaced it, a moment later: the panel never showed it
    def noted(progress, should_cancel):
        progress(0.02, "note: about 4,000 objects and no time budget: ... Ctrl-C stops them "
                       "and keeps the best certified packing so far; --time-budget / "
                       "time_budget sets a limit.")
        progress(0.03, "phase 1")
        return 1

    snap = _job(noted).snapshot()
    assert snap.message == "phase 1" and len(snap.notes) == 1
    assert summary.in_blender_words(snap.notes[0]).endswith(
        "Finish Now stops them and keeps the best certified packing so far; Time Budget "
        "sets a limit.")


def test_job_reports_progress_result_and_errors():
    seen = []

    def ok(progress, should_cancel):
        progress(0.5, "half")
        seen.append(should_cancel())
        return 42

    job = _job(ok)
    snap = job.snapshot()
    assert (snap.state, snap.fraction, snap.message, job.result) == ("done", 1.0, "half", 42)
    assert seen == [False]

    def bad_input(progress, should_cancel):
        raise MeshError("Container mesh 'Box' is not closed.")

    job = _job(bad_input)
    assert job.snapshot().state == "failed" and job.error == "Container mesh 'Box' is not closed."

    def bug(progress, should_cancel):
        raise ZeroDivisionError("oops")

    job = _job(bug)
    assert job.snapshot().state == "failed"
    assert "internal error (ZeroDivisionError: oops)" in job.error
    assert not worker.busy()


def _waiting(progress, should_cancel):
    while not should_cancel():
        time.sleep(0.01)
    return "best so far"


def test_cancel_discards_and_finish_early_keeps():
    job = worker.Job("Test", _waiting).start()
    assert worker.busy() and job.snapshot().state == "running"
    job.cancel()
    assert job.wait(5.0)
    assert job.snapshot().state == "cancelled" and job.result is None
    job.release()

    job = worker.Job("Test", _waiting).start()
    job.finish_early()
    assert job.snapshot().stopping or job.wait(5.0)
    assert job.wait(5.0)
    assert job.snapshot().state == "done" and job.result == "best so far"
    job.release()
    assert not worker.busy()


def test_one_job_at_a_time():
    first = worker.Job("First", _waiting).start()
    try:
        with pytest.raises(worker.BusyError, match="First is still running"):
            worker.Job("Second", _waiting).start()
        assert worker.active_job() is first
    finally:
        worker.abandon(timeout=5.0)
    assert not worker.busy() and first.snapshot().state == "cancelled"
    second = worker.Job("Second", lambda p, c: threading.current_thread().name).start()
    second.wait(5.0)
    second.release()
    assert second.result == "jampacked Second"


def test_collection_properties_and_panel_lines():
    types = [TypeRecord(name, None, None, 0.5, np.eye(4), 1.0) for name in ("apple", "lemon")]
    packing = Packing(
        "box:10x10x10", None, np.eye(4), 1000.0, types, np.array([0, 0, 1]),
        np.tile([1.0, 0, 0, 0], (3, 1)), np.zeros((3, 3)), np.ones(3),
        report=RunReport(fidelity="low", stopped=None), seed=7,
        metrics={"count": 3, "count_per_type": [2, 1], "density": 0.41, "tvd": 0.02,
                 "nni_per_type": [1.2, None], "nni_mean": 1.2},
        timings={"total": 2.5},
        certificate={"certified": True, "worst_overlap": 1e-5, "worst_outside": 0.0,
                     "min_pair_gap": None, "clearance": 0.0})
    props = summary.collection_properties(packing)
    assert props["nni_per_type"] == [1.2, -1.0]
    assert "min_pair_gap" not in props and props["certified"] is True
    assert all(isinstance(v, (bool, int, float, str, list)) for v in props.values())
    rows = dict(summary.panel_lines({summary.PREFIX + k: v for k, v in props.items()}))
    assert rows["Density"] == "41.0%" and rows["Certified"] == "yes"
    assert rows["apple"].startswith("2  (66.7% / 50.0%)  NNI 1.20")
    assert rows["lemon"].endswith("NNI -")
    # what the result holds now, where it differs from the packing (volumes 1, box 1000)
    stored = {summary.PREFIX + k: v for k, v in props.items()}
    assert summary.density_now(stored, {0: 2.0, 1: 1.0}) == pytest.approx(0.003)
    assert "Holds now" not in dict(summary.panel_lines(stored, now=(3, 0.41)))
    assert dict(summary.panel_lines(stored, now=(3, 0.2)))["Holds now"] == "3 objects, 20.0%"
    assert dict(summary.panel_lines(stored, now=(2, 0.002)))["Holds now"] == \
        "2 objects, 0.2%"
    old = {k: v for k, v in stored.items() if not k.endswith("volume") and
           not k.endswith("volumes")}  # a result made before the volumes were stored
    assert summary.density_now(old, {0: 2.0}) is None
    assert dict(summary.panel_lines(old, now=(2, None)))["Holds now"] == "2 objects"
    # gaps in millimetres, as exported (a scene in metres: 1000 mm per unit); None: "-"
    gaps = {summary.PREFIX + k: v for k, v in props.items()}
    gaps.update({summary.PREFIX + "clearance": 0.0002, summary.PREFIX + "min_pair_gap": 0.00021})
    rows = dict(summary.panel_lines(gaps, 1000.0))
    assert rows["Min gap objects"] == "0.21 mm" and rows["Min gap wall"] == "-"
    assert dict(summary.panel_lines(gaps))["Min gap objects"] == "0.00021"
    colours = {summary.type_colour(i) for i in range(8)}
    assert len(colours) == 8


def test_engine_messages_in_blender_words():
    # the engine's advice names command-line options; Blender users change objects and fields
    text = ("type rod (share 50%) was not placed at all: ... Scale the objects down "
            "(--type-scale / type_scale), the container up (--container-size / "
            "container_size), or remove the type.")
    assert summary.in_blender_words(text) == (
        "Type rod (share 50%) was not placed at all: ... Scale the objects down (the type "
        "objects' scale), the container up (the container object's scale), or remove the "
        "type.")
    for budget in ("--time-budget", "--time-budget / time_budget"):
        assert summary.in_blender_words(f"give a larger {budget}, or none.") == \
            "Give a larger Time Budget, or none."
    # messages written for the command line and for mesh files
    from jampacked.core.errors import InputError
    from jampacked.export.parts import require_gap

    with pytest.raises(InputError) as err:
        require_gap(0.0)
    assert summary.in_blender_words(str(err.value)).endswith(
        "Re-pack with a Clearance (e.g. 0.2 mm), or export in Union or Connect mode.")
    from jampacked.core.errors import MeshError
    from jampacked.core.meshes import mesh_from_arrays

    with pytest.raises(MeshError) as err:  # faces that cancel out: no file to export again
        mesh_from_arrays(np.eye(3), np.array([[0, 1, 2], [0, 2, 1]]), name="Box",
                         role="container")
    assert summary.in_blender_words(str(err.value)).endswith(
        "Check that it is the right object, and make it a closed solid in Edit Mode."), err.value
    assert summary.in_blender_words("Fix: fill the holes; then export again.") == \
        "Fix: fill the holes; then pack again."
    assert summary.in_blender_words(
        "Try --fidelity high / fidelity='high' (finer grids)") == \
        "Try Fidelity High (finer grids)"
    assert summary.in_blender_words(
        "a finer --resolution (e.g. 0.1) or none avoids it; --mode parts keeps every object "
        "apart.") == "A finer Resolution (e.g. 0.1) or none avoids it; Parts mode keeps every " \
        "object apart."
    assert summary.in_blender_words("Scale the objects down (--type-scale / type_scale, "
                                    "0.5)") == "Scale the objects down (the type objects' " \
        "scale, 0.5)"
    # connect's advice named --connector and --mode in the add-on's Export
    assert summary.in_blender_words(
        "connect made 2 bodies instead of one; nothing was written: ... e.g. --connector "
        "1.5, or export with --mode union or --mode parts.") == (
        "Connect made 2 bodies instead of one; nothing was written: ... e.g. Connector 1.5, "
        "or export in Union or Parts mode.")
    # a union with a shell whose objects lie loose in it
    assert summary.in_blender_words(
        "In the print they rattle in its cavity. To tie every object to the shell, export "
        "with --mode connect.") == ("In the print they rattle in its cavity. To tie every "
                                    "object to the shell, export in Connect mode.")


def test_the_mix_warnings_in_blender_words():
    """Both kinds of advice an off mix gets name only what a Blender user changes."""
    from jampacked.core.report import PhaseStats
    from jampacked.core.run_warnings import run_warnings

    half = np.array([0.5, 0.5])
    few = np.array([0.05, 0.95])
    # one beyond the best mix; far off; a small share far short within the tolerance
    for counts, shares in (([4, 7], half), ([30, 70], half), ([2, 98], few)):
        c = np.array(counts)
        tvd = 0.5 * float(np.abs(c / c.sum() - shares).sum())
        (w,) = run_warnings(["apple", "plum"], shares, c, tvd, 0.04, PhaseStats(), None,
                            None, None, 1)
        words = summary.in_blender_words(w)
        assert "Mix Tolerance" in words
        for cli in ("--", "mix_tolerance", "type_scale", "container_size"):
            assert cli not in words, (cli, words)


def test_the_drain_warning_in_blender_words(monkeypatch):
    # the add-on exports with +z up: the advice to give another up axis is left out
    from types import SimpleNamespace

    from jampacked.export import assemble
    from jampacked.export.options import ExportOptions

    monkeypatch.setattr(assemble, "drain_cover", lambda *a: [0])
    packing = SimpleNamespace(types=[SimpleNamespace(name="lemon")], type_index=[0])
    options = ExportOptions(mode="union", shell=2.0, drain=3.0)
    text, = assemble._drain_warning(packing, SimpleNamespace(solids=[]), options, (0, 0, -38))
    assert "--up" in text and "--open-plane or --window" in text
    assert summary.in_blender_words(text) == (
        "The drain hole at (0, 0, -38) is covered: lemon #0 sits within its radius above "
        "it, so liquid or powder may not reach it. Open the shell with an Opening (Plane or "
        "Window).")
    # a shell opened already is not told to open: the opening lets the liquid out
    from jampacked.export.options import Opening

    opened = ExportOptions(mode="union", shell=2.0, drain=3.0,
                           opening=Opening(axis="+z", at=0.75))
    text, = assemble._drain_warning(packing, SimpleNamespace(solids=[]), opened, (0, 0, -38))
    assert "--open-plane" not in text and "through the shell's plane cut instead" in text
    assert summary.in_blender_words(text).endswith(
        "may not reach it. The liquid or powder can leave through the shell's plane cut "
        "instead.")


def test_export_options_from_the_panel():
    engine = load_standalone("engine")
    opts = engine.export_options("PARTS", 2.0, "PLANE", "+z", 0.7, 0.0, 1.0, 0.0, 0.0, True)
    assert opts.mode == "parts" and opts.shell is None and opts.opening is None
    assert opts.split_files
    opts = engine.export_options("CONNECT", 1.5, "WINDOW", "-x", 0.7, 8.0, 2.0, 0.0, 0.1, True)
    assert (opts.shell, opts.opening.kind, opts.opening.axis, opts.opening.size) == \
        (1.5, "window", "-x", 8.0)
    assert opts.drain == 2.0 and opts.connector is None and opts.resolution == 0.1
    assert not opts.split_files and opts.fill_voids
    opts = engine.export_options("UNION", 0.0, "NONE", "+z", 0.7, 0.0, 0.0, 0.0, 0.0, False,
                                 False)
    assert opts.mode == "union" and not opts.fill_voids
    with pytest.raises(InputError):
        engine.export_options("UNION", 1.0, "WINDOW", "+z", 0.5, 0.0, 0.0, 0.0, 0.0, False)


# ------------------------------------------------------------------------------ manifest


def _manifest() -> dict:
    return tomllib.loads((ADDON / "blender_manifest.toml").read_text(encoding="utf-8"))


def test_manifest_is_valid():
    data = _manifest()
    # the wheels it lists (written by build.py) need not be downloaded for this check
    assert build.validate_manifest(data, ADDON, check_files=False) == []
    assert data["schema_version"] == "1.0.0" and data["id"] == "jampacked"
    assert data["blender_version_min"] == "4.2.0" and data["license"] == ["SPDX:MIT"]
    assert "files" in data["permissions"]
    assert not any("numpy" in w for w in data["wheels"])
    init = ast.parse((ADDON / "__init__.py").read_text(encoding="utf-8"))
    assigned = {t.id for node in init.body if isinstance(node, ast.Assign)
                for t in node.targets if isinstance(t, ast.Name)}
    assert "bl_info" not in assigned  # an extension has a manifest instead


def test_manifest_validation_catches_mistakes(tmp_path):
    data = _manifest()
    bad = dict(data, tagline="Packs things.", id="jam-packed", blender_version_min="4.1.0",
               permissions={"files": "Writes files."},
               wheels=["./wheels/numpy-1.26.4-cp311-cp311-win_amd64.whl"])
    del bad["license"]
    problems = "\n".join(build.validate_manifest(bad, tmp_path))
    assert "missing required field 'license'" in problems
    bad["license"] = ["SPDX:MIT"]
    problems = "\n".join(build.validate_manifest(bad, tmp_path))
    for text in ("tagline must not end with punctuation", "id 'jam-packed'",
                 "older than 4.2.0", "permission 'files'", "numpy must not be bundled",
                 "does not exist", "no wheel of jampacked", "no linux-x64 wheel of numba"):
        assert text in problems, text


def test_wheel_names_and_manifest_list():
    wheels = [Path(n) for n in (
        "jampacked-0.1.0-py3-none-any.whl",
        "numba-0.68.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl",
        "scipy-1.17.1-cp311-cp311-win_amd64.whl",
        "llvmlite-0.50.0-cp311-cp311-macosx_12_0_arm64.whl")]
    parsed = [build.Wheel.parse(w) for w in wheels]
    assert [w.platform() for w in parsed] == [None, "linux-x64", "windows-x64", "macos-arm64"]
    assert parsed[1].distribution == "numba" and parsed[1].version == "0.68.1"
    text = build.with_wheels((ADDON / "blender_manifest.toml").read_text(), wheels,
                             ["linux-x64"])
    data = tomllib.loads(text)
    assert data["wheels"] == [f"./wheels/{w.name}" for w in wheels]
    assert data["platforms"] == ["linux-x64"] and "permissions" in data


def test_build_without_wheels(tmp_path):
    (out,) = build.build(["linux-x64"], wheels=False, output_dir=tmp_path,
                         blender_check=False)
    assert out.name == f"jampacked-{_manifest()['version']}.zip"
    with zipfile.ZipFile(out) as zf:
        names = set(zf.namelist())
        manifest = tomllib.loads(zf.read("blender_manifest.toml").decode())
    assert {"__init__.py", "operators.py", "bridge.py", "worker.py", "ui.py", "props.py",
            "engine.py", "summary.py", "blender_manifest.toml"} <= names
    assert "build.py" not in names and not any(n.startswith("wheels/") for n in names)
    assert manifest["wheels"] == [] and manifest["platforms"] == ["linux-x64"]


def test_scene_units_to_millimetres():
    units = load_standalone("units")
    assert units.mm_per_unit("METRIC", 1.0) == 1000.0  # Blender's default scene
    assert units.mm_per_unit("METRIC", 0.001) == 1.0
    assert units.mm_per_unit("IMPERIAL", 0.0254) == pytest.approx(25.4)
    assert units.mm_per_unit("NONE", 1.0) == 1.0
    assert units.units_line("METRIC", 1.0) == "1 BU = 1 m, exported in mm"
    assert units.units_line("METRIC", 0.001) == "1 BU = 1 mm, exported in mm"
    assert units.units_line("IMPERIAL", 0.0254) == "1 BU = 2.54 cm, exported in mm"
    assert units.units_line("NONE", 1.0) == "No scene units: 1 BU exported as 1 mm"


def test_scaled_packing_is_the_same_print_larger():
    """Scaling a packing, its meshes and the export lengths by k moves every placed vertex
    to k times its place."""
    import numpy as np

    from jampacked.core.packing import Packing, TypeRecord

    engine = load_standalone("engine")
    rng = np.random.default_rng(0)
    local = np.eye(4)
    local[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    local[:3, 3] = rng.normal(size=3)
    packing = Packing(
        container_path="blender:Box", container_sha256=None, frame_from_file=np.eye(4),
        container_volume=8.0,
        types=[TypeRecord("t", None, None, 1.0, local, volume=0.5)],
        type_index=np.zeros(2, np.int64),
        rotations=np.array([[1.0, 0, 0, 0], [0.0, 1.0, 0, 0]]),
        translations=rng.normal(size=(2, 3)), scales=np.ones(2),
        inputs=PackInputs(clearance=0.002))
    verts = rng.normal(size=(4, 3))
    tri = engine.Triangles("t", verts, np.array([[0, 1, 2]]), np.zeros(1, np.int64), 1)
    box = engine.Triangles("Box", verts * 3, np.array([[0, 1, 2]]), np.zeros(1, np.int64), 1)
    options = engine.export_options("CONNECT", 0.002, "WINDOW", "+z", 0.7, 0.01, 0.003,
                                    0.001, 0.0001, False)
    out, cbox, (ctri,), copts = engine.scaled(packing, box, [tri], options, 1000.0)

    def placed(p, t):
        m = p.matrices() @ p.types[0].local_from_file
        return np.einsum("nij,vj->nvi", m[:, :3, :3], t.vertices) + m[:, None, :3, 3]

    np.testing.assert_allclose(placed(out, ctri), 1000.0 * placed(packing, tri), atol=1e-9)
    np.testing.assert_allclose(cbox.vertices, 3000.0 * verts)
    assert out.container_volume == pytest.approx(8e9) and out.types[0].volume == \
        pytest.approx(5e8)
    assert out.inputs.clearance == pytest.approx(2.0)
    assert (copts.shell, copts.drain, copts.connector, copts.resolution, copts.opening.size) \
        == pytest.approx((2.0, 3.0, 1.0, 0.1, 10.0))
    assert packing.translations is not out.translations and packing.inputs.clearance == \
        0.002  # the input is unchanged


def test_progress_log_is_throttled():
    now = [0.0]
    log = worker.ProgressLog("Packing", clock=lambda: now[0])

    def snap(fraction, message="phase 1"):
        return worker.Snapshot(worker.RUNNING, fraction, message, False, now[0])

    assert log.line(snap(0.0)) == "Jampacked packing:   0% phase 1 (0.0 s)"
    now[0] = 0.5
    assert log.line(snap(0.03)) is None  # under 5% and 2 s since the last line
    assert log.line(snap(0.06)) is not None  # 5% further
    now[0] = 1.0
    assert log.line(snap(0.07)) is None
    now[0] = 2.6
    assert log.line(snap(0.07, "phase 2")) == "Jampacked packing:   7% phase 2 (2.6 s)"


def test_a_blender_packing_stays_as_certified_through_its_name_and_units():
    # the engine renamed the container to blender:<name> after pack() recorded the digest,
    # and scaled() to millimetres changed every length: each unedited Blender export was
    # certified again and said the packing had been edited
    import trimesh

    from jampacked.core.packing_digest import placements_status

    engine = load_standalone("engine")

    def tris(mesh, name):
        f = np.asarray(mesh.faces, np.int64)
        return engine.Triangles(name, np.asarray(mesh.vertices, np.float64), f,
                                np.arange(len(f)), len(f))

    box = tris(trimesh.creation.box(extents=(0.03, 0.03, 0.03)), "Cube")
    ball = tris(trimesh.creation.icosphere(2, radius=0.004), "Ball")
    out = engine.pack_triangles(box, [ball], [1.0], seed=1, clearance=0.0005, fidelity="low",
                                time_budget=2.0, progress=lambda f, m: None,
                                should_cancel=lambda: False)
    assert out.packing.container_path == "blender:Cube" and out.packing.n > 0
    assert placements_status(out.packing) == "as certified"
    again = engine.packing_from_json(out.json_text)
    assert placements_status(again) == "as certified"
    mm, *_ = engine.scaled(again, box, [ball], engine.export_options(
        "UNION", 0.0, "NONE", "+z", 0.7, 0.0, 0.0, 0.0, 0.0, False), 1000.0)
    assert placements_status(mm) == "as certified"
    assert mm.certificate["clearance"] == pytest.approx(0.5)
    assert mm.report.container_grid_spacing == pytest.approx(
        1000.0 * again.report.container_grid_spacing)


@pytest.mark.parametrize(("engine", "blender"), [
    # the export works in millimetres: its numbers read as bare lengths, and a field's
    # suggestion typed as it read gave metres in a scene in metres
    ("Try thicker struts than these (2.29 across), e.g. --connector 4.6, or export with "
     "--mode union or --mode parts.",
     "Try thicker struts than these (2.29 mm across), e.g. Connector 4.6 mm, or export in "
     "Union or Parts mode."),
    ("'Cube 25, an instance' and 'P1 3' are 0.839 apart (0.161 under the clearance 1)",
     "'Cube 25, an instance' and 'P1 3' are 0.839 mm apart (0.161 mm under the clearance "
     "1 mm)"),
    ("the drain opens 4 away from it and 0.5 lower, at",
     "The drain opens 4 mm away from it and 0.5 mm lower, at"),
    ("the cavity's drain opens 4 away from the shell's 2 thick wall",
     "The cavity's drain opens 4 mm away from the shell's 2 mm thick wall"),
    ("'X' is up to 15.32 units across, at (-39.86, -21.21, 174.3); the container spans "
     "(-50, -50, -50) to (50, 50, 50).",
     "'X' is up to 15.32 mm across, at (-39.86, -21.21, 174.3) mm; the container spans "
     "(-50, -50, -50) mm to (50, 50, 50) mm."),
    ("--resolution saved 138 triangles (surfaces moved at most 0.124 mm); 2 bodies",
     "Resolution saved 138 triangles (surfaces moved at most 0.124 mm); 2 bodies"),
    ("--shell 1e-05 is too thin", "Shell 1e-05 mm is too thin"),
    # a decimal already in mm stays whole; names in quotes are names
    ("Clearance 0.25 mm, shell 2.5 mm thick", "Clearance 0.25 mm, shell 2.5 mm thick"),
    ("'Strut 2 long' and 'Box (1, 2, 3)' are 0.5 apart",
     "'Strut 2 long' and 'Box (1, 2, 3)' are 0.5 mm apart"),
])
def test_export_messages_in_millimetres(engine, blender):
    assert summary.export_in_mm(summary.in_blender_words(engine)) == blender
