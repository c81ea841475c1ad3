"""The `jampacked` command line, end to end on a small scene (box, two convex polyhedra)."""

from __future__ import annotations

import contextlib
import io
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.cli import pack_cmd
from jampacked.cli.args import UsageError
from jampacked.cli.main import main
from jampacked.cli.parser import build_parser
from jampacked.cli.preview import section_axis, write_preview
from jampacked.cli.scene import parse_type_arg, resolve_scene, resolve_shares, shares_note
from jampacked.core.errors import InputError
from jampacked.core.metrics import compute_metrics
from jampacked.core.packing_json import load_packing

P1 = mesh_path("polyhedra/convex5/polytope1.obj")
P3 = mesh_path("polyhedra/convex5/polytope3.obj")

SMALL = ["--fidelity", "low", "--time-budget", "4", "--seed", "1"]
#: for runs that need a packing but not a good one: a 1 s budget, on a box (20 units) where
#: phase 1 places objects in a fraction of it (the late passes would fill any budget)
BRIEF = ["box:20x20x20", "--type", str(P1), "--fidelity", "low", "--time-budget", "1",
         "--seed", "1"]


def run(argv: list[str]) -> tuple[int, str, str]:
    """main(argv) with stdout and stderr captured (usable in module-scoped fixtures)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def packed(tmp_path_factory):
    """One small pack with a preview: (folder, json path, png path, rc, stdout, stderr)."""
    d = tmp_path_factory.mktemp("cli")
    out, png = d / "packing.json", d / "preview.png"
    rc, so, se = run(["pack", "box:30x30x30", "--type", f"{P1}=40%", "--type", str(P3),
                      *SMALL, "-o", str(out), "--preview", str(png)])
    return d, out, png, rc, so, se


# --------------------------------------------------------------------------- pack


def test_pack_writes_certified_packing(packed):
    _, out, _, rc, _, se = packed
    assert rc == 0, se
    p = load_packing(out)
    assert p.n > 0
    assert p.certificate["certified"] is True
    assert p.certificate["worst_overlap"] <= p.certificate["tol"]
    assert p.container_path == "box:30x30x30"
    assert [t.name for t in p.types] == ["polytope1", "polytope3"]
    assert [t.share for t in p.types] == pytest.approx([0.4, 0.6])
    assert p.report.fidelity == "low" and p.seed == 1


def test_metrics_recomputed_from_json_match(packed):
    out = packed[1]
    p = load_packing(out)
    again = compute_metrics(p.type_index, p.translations, [t.volume for t in p.types],
                            [t.share for t in p.types], p.container_volume)
    for key in ("count", "count_per_type", "density", "tvd", "shares", "nni_mean"):
        assert again[key] == pytest.approx(p.metrics[key], rel=1e-9), key
    for a, b in zip(again["nni_per_type"], p.metrics["nni_per_type"], strict=True):
        assert (a is None and b is None) or a == pytest.approx(b, rel=1e-9)


def test_pack_prints_summary(packed):
    _, out, png, _, so, _ = packed
    for word in ("polytope1", "polytope3", "density", "TVD", "NNI", "certified",
                 "worst overlap", "worst wall violation", "repair", "place & grow", "total"):
        assert word in so, word
    assert str(out) in so and str(png) in so


def test_summary_gives_millimetres_for_a_3mf_container(packed):
    # a 3MF's coordinates are read in millimetres (its declared unit converted); other
    # formats carry no unit and the summary says "units"
    from dataclasses import replace

    from rich.console import Console

    from jampacked.cli.reports import print_summary

    p = load_packing(packed[1])
    for path, unit in (("/x/jar.3MF", "mm³"), ("/x/jar.stl", "units³"),
                       ("box:30x30x30", "units³")):
        console = Console(record=True, width=200)
        print_summary(replace(p, container_path=path), console)
        text = console.export_text()
        line = next(ln for ln in text.splitlines() if "volume" in ln and "container" in ln)
        assert line.strip(" │").endswith(unit), (path, line)


def test_preview_is_a_png_with_content(packed):
    png = packed[2]
    import matplotlib.image as mpimg

    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(png)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 600
    rgb = np.rint(img[..., :3] * 255).astype(np.int64)
    packed_rgb = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
    assert len(np.unique(packed_rgb)) > 20  # panels, outlines, filled objects, text
    # the two types' fills (tab10 blue and orange) are present
    for colour in ((31, 119, 180), (255, 127, 14)):
        assert np.any(np.all(np.abs(rgb - colour) <= 2, axis=-1)), colour
    assert not list(png.parent.glob(".preview.png.*"))  # no temp file left behind


def test_write_preview_rejects_bad_heights(packed, tmp_path):
    p = load_packing(packed[1])
    with pytest.raises(InputError, match="between 0 and 1"):
        write_preview(p, tmp_path / "x.png", heights=(0.5, 1.5))
    with pytest.raises(InputError, match="does not exist"):
        write_preview(p, tmp_path / "missing" / "x.png")


def test_preview_axis_is_z_unless_the_container_is_thin_across_another():
    assert section_axis(np.array([2.5, 0.5, 2.5])) == 1  # a torus lying in x-z (Y-up)
    assert section_axis(np.array([0.303, 0.515, 1.0])) == 0
    assert section_axis(np.array([0.943, 1.69, 1.718])) == 2  # Spot: under twice as long
    assert section_axis(np.array([3.0, 4.0, 1.0])) == 2
    assert section_axis(np.array([2.5, 0.5, 2.5]), "x") == 0
    with pytest.raises(InputError, match="auto, x, y or z"):
        section_axis(np.ones(3), "w")


def test_preview_of_a_container_thin_across_y_cuts_across_y(tmp_path):
    out, png = tmp_path / "p.json", tmp_path / "flat.png"
    rc, _, se = run(["pack", "box:40x13x40", "--type", str(P1), "--fidelity", "low",
                     "--time-budget", "2", "--seed", "1", "-q", "-o", str(out),
                     "--preview", str(png)])
    assert rc == 0, se
    import matplotlib.image as mpimg

    flat = mpimg.imread(png)
    write_preview(load_packing(out), tmp_path / "z.png", axis="z")
    along_z = mpimg.imread(tmp_path / "z.png")
    # panels of the 40 x 40 x-z section are square; the x-y ones 40 x 13 (at their lowest)
    assert flat.shape[1] == along_z.shape[1] and flat.shape[0] > 1.5 * along_z.shape[0]
    rgb = np.round(flat[..., :3] * 255).astype(int)
    assert np.any(np.all(np.abs(rgb - (31, 119, 180)) <= 2, axis=-1))  # objects were cut


def test_info_prints_summary_and_checks_sources(packed, capsys):
    out = packed[1]
    assert main(["info", str(out)]) == 0
    so = capsys.readouterr().out
    assert "polytope1" in so and "density" in so and "certified" in so
    assert "sources: all 2 mesh files present and unchanged" in so


def test_info_gives_the_run_s_warnings_as_recorded(packed, capsys, tmp_path):
    """The warnings a packing records are the run's, not news ("warning:" read as if info
    had found something), and one repair round is "1 round"."""
    from jampacked.core.packing import save_packing
    from jampacked.core.report import RepairStats

    p = load_packing(packed[1])
    p.report.warnings = ["the time budget ended early"]
    p.report.repair = RepairStats(rounds=1, moved=2)
    save_packing(p, tmp_path / "warned.json")
    assert main(["info", str(tmp_path / "warned.json")]) == 0
    captured = capsys.readouterr()
    assert "warned when packed: the time budget ended early" in captured.err
    assert "warning:" not in captured.err
    assert "1 round, 2 moved, 0 removed" in captured.out


def test_info_lists_the_attempts_and_the_time_of_those_not_kept(packed, capsys):
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["report"]["attempts"] = [
        {"density": 0.412, "count": 30, "seconds": 2.5, "phase1": 1.0, "phase2": 0.5,
         "extra": 1.0, "stopped": None},
        {"density": 0.398, "count": 29, "seconds": 1.5, "phase1": 0.5, "phase2": 0.5,
         "extra": 0.5, "stopped": "deadline"}]
    doc["timings"]["other_attempts"] = 1.5
    edited = d / "attempts.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0
    so = capsys.readouterr().out
    assert "attempt 1" in so and "30 objects, 41.2%, 2.5 s (kept)" in so
    assert "attempt 2" in so and "29 objects, 39.8%, 1.5 s" in so
    assert "attempts not kept" in so


def test_info_shows_the_certified_densities_and_the_attempt_kept_after_them(packed, capsys):
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["report"]["attempts"] = [
        {"density": 0.412, "count": 30, "seconds": 2.5, "phase1": 1.0, "phase2": 0.5,
         "extra": 1.0, "stopped": None, "certified": 0.371, "kept": False},
        {"density": 0.398, "count": 29, "seconds": 1.5, "phase1": 0.5, "phase2": 0.5,
         "extra": 0.5, "stopped": None, "certified": 0.398, "kept": True},
        {"density": 0.301, "count": 22, "seconds": 1.5, "phase1": 0.5, "phase2": 0.5,
         "extra": 0.5, "stopped": None}]
    edited = d / "attempts.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0
    so = capsys.readouterr().out
    lines = {n: next(line for line in so.splitlines() if f"{n} objects" in line)
             for n in (30, 29, 22)}
    assert "30 objects, 41.2%, 2.5 s, certified 37.1%" in lines[30]
    assert "(kept)" not in lines[30]
    assert "29 objects, 39.8%, 1.5 s, certified 39.8% (kept)" in lines[29]
    assert "certified" not in lines[22] and "(kept)" not in lines[22]


def test_info_says_why_the_attempts_ended_before_the_budget(packed, capsys):
    # an independent check: a crate of bricks ended 1 s into a 30 s budget, and nothing
    # said why
    from jampacked.core.placement import REPEATED, STACK_FULL

    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["report"]["stopped"] = None  # placement ran to its end
    one = {"density": 0.82, "count": 258, "seconds": 0.3, "phase1": 0.3, "phase2": 0.0,
           "extra": 0.0, "stopped": STACK_FULL}
    for name, attempts, said in (
            ("stack", [one], f"after 1 attempt: {STACK_FULL}"),
            ("repeat", [{**one, "stopped": None}, {**one, "stopped": REPEATED}],
             f"after 2 attempts: {REPEATED}"),
            ("none", [{**one, "stopped": None}], None)):
        doc["report"]["attempts"] = attempts
        edited = d / f"{name}.json"
        edited.write_text(json.dumps(doc))
        assert main(["info", str(edited)]) == 0
        so = " ".join(capsys.readouterr().out.split())
        if said is None:
            assert "attempts ended" not in so
        else:
            assert "attempts ended" in so and said.split()[-1] in so


def test_info_says_which_attempt_skipped_its_passes(packed, capsys):
    from jampacked.core.placement import BEHIND

    d, out, *_ = packed
    doc = json.loads(out.read_text())
    one = {"density": 0.70, "count": 89, "seconds": 0.9, "phase1": 0.8, "phase2": 0.0,
           "extra": 0.1, "stopped": None}
    doc["report"]["attempts"] = [one, {**one, "density": 0.32, "count": 40, "extra": 0.0,
                                       "stopped": BEHIND}]
    edited = d / "behind.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0
    so = " ".join(capsys.readouterr().out.replace("│", " ").split())  # rows may wrap
    assert ("attempt 1 89 objects, 70.0%, 0.9 s (kept) attempt 2 40 objects, 32.0%, 0.9 s, "
            "no extra passes: too far behind to catch up └") in so

def test_info_gives_the_least_gaps_or_says_none_came_near(packed, capsys):
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["certificate"].update(clearance=0.3, min_pair_gap=0.3125, min_wall_gap=None)
    del doc["certificate"]["placements_sha256"]  # as an older jampacked wrote it
    edited = d / "gaps.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0
    rows = {line.split("│")[1].strip(): line.split("│")[2].strip()
            for line in capsys.readouterr().out.splitlines() if line.count("│") >= 3}
    assert rows["min gap objects"] == "0.312  (clearance 0.3)"
    assert rows["min gap wall"] == "no object that close  (clearance 0.3)"


def test_info_reports_changed_source(packed, capsys):
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["types"][0]["sha256"] = "0" * 64
    edited = d / "edited.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 1
    err = capsys.readouterr().err
    assert "polytope1" in err and "changed" in err


def test_info_says_when_the_placements_changed_after_certification(packed, capsys):
    # an edited packing still read "certified: yes" with its old figures
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["placements"][0]["translation"][0] += 0.5
    doc["placements"][0]["matrix"][0][3] += 0.5
    edited = d / "moved.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 1
    captured = capsys.readouterr()
    rows = {line.split("│")[1].strip(): line.split("│")[2].strip()
            for line in captured.out.splitlines() if line.count("│") >= 3}
    assert rows["certified"].startswith("no longer")
    assert "placements: changed after the packing was certified" in " ".join(
        captured.err.split())
    assert main(["info", str(out)]) == 0  # the file as written


def test_info_says_when_its_figures_do_not_follow_from_the_placements(packed, capsys):
    """A density edited in the file read "90.0%" with exit 0, where a batch rerun finds the
    same edit and packs the scene again."""
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    true = doc["metrics"]["density"]
    doc["metrics"]["density"] = 0.9
    edited = d / "figures.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 1
    err = " ".join(capsys.readouterr().err.split())
    assert (f"metrics: its metrics.density reads 0.9 but its placements give {true:.6g} "
            "(edited after it was made?): the figures above are not this packing's") in err
    del doc["metrics"]["density"]  # a figure the file does not hold is not an edit
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0


def test_info_says_when_only_the_clearance_asked_changed(packed, capsys):
    # it read "the placements were changed after certification"
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    doc["inputs"]["clearance"] = doc["certificate"]["clearance"] + 0.5
    edited = d / "clearance.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 1
    captured = capsys.readouterr()
    text = " ".join(captured.out.replace("│", " ").split())  # the table wraps its cells
    assert "no longer: the packing's inputs ask another clearance than the" in text
    assert "placements were changed" not in text
    err = " ".join(captured.err.split())
    assert "clearance: the packing asks a clearance of" in err and "but was certified with" \
        in err


def test_info_says_when_a_certified_packing_records_no_digest(packed, capsys):
    # with its digest deleted, an edited packing read "certified: yes"
    d, out, *_ = packed
    doc = json.loads(out.read_text())
    del doc["certificate"]["placements_sha256"]
    edited = d / "no-digest.json"
    edited.write_text(json.dumps(doc))
    assert main(["info", str(edited)]) == 0  # an older jampacked's file is not an error
    text = " ".join(capsys.readouterr().out.split())
    assert "certified │ yes, by an older jampacked or with its digest" in text
    assert "'export' certifies them again" in text


def test_ctrl_c_saves_best_certified_packing(tmp_path, monkeypatch, capsys):
    """The first Ctrl-C makes should_cancel() true; the packing so far is certified and saved."""
    real_pack = pack_cmd.pack
    seen = {}
    # what was installed before (importing bpy in the add-on tests sets SIG_IGN)
    before = signal.getsignal(signal.SIGINT)

    def interrupted_pack(*args, should_cancel, **kwargs):
        assert not should_cancel()
        polls = iter(range(10**9))

        def ctrl_c_once_objects_are_placed() -> bool:
            if next(polls) == 300:
                signal.raise_signal(signal.SIGINT)  # what Ctrl-C does
            return should_cancel()

        packing = real_pack(*args, should_cancel=ctrl_c_once_objects_are_placed, **kwargs)
        seen["cancel"] = should_cancel()
        return packing

    monkeypatch.setattr(pack_cmd, "pack", interrupted_pack)
    out = tmp_path / "p.json"
    rc = main(["pack", "box:30x30x30", "--type", str(P1), *SMALL, "-q", "-o", str(out)])
    assert seen["cancel"] is True
    assert rc == 130
    assert "interrupted" in capsys.readouterr().err
    p = load_packing(out)
    assert p.n > 0
    assert p.report.stopped == "cancelled" and p.certificate["certified"] is True
    assert signal.getsignal(signal.SIGINT) is before  # restored


def test_ctrl_c_before_any_object_keeps_the_output_files(tmp_path, monkeypatch, capsys):
    """Interrupted before anything was placed: an empty packing is no result, so the files
    from an earlier run stay as they were (they were replaced by a 0-object packing)."""
    real_pack = pack_cmd.pack

    def interrupted_at_once(*args, should_cancel, **kwargs):
        signal.raise_signal(signal.SIGINT)
        return real_pack(*args, should_cancel=should_cancel, **kwargs)

    monkeypatch.setattr(pack_cmd, "pack", interrupted_at_once)
    out, preview = tmp_path / "p.json", tmp_path / "p.png"
    out.write_text('{"an earlier": "packing"}')
    preview.write_bytes(b"an earlier preview")
    rc = main(["pack", "box:30x30x30", "--type", str(P1), *SMALL, "-q", "-o", str(out),
               "--preview", str(preview)])
    assert rc == 130
    assert "nothing saved" in " ".join(capsys.readouterr().err.split())
    assert out.read_text() == '{"an earlier": "packing"}'
    assert preview.read_bytes() == b"an earlier preview"


@pytest.mark.parametrize("failing", ["save_packing", "write_preview"])
def test_a_full_disk_is_an_error_that_names_the_file(failing, tmp_path, monkeypatch, capsys):
    """The file system refusing the packing or its preview (a full disk) ended in a
    traceback; it is an error naming the file and the cause, and what was saved."""
    import jampacked.cli.preview as preview_module
    import jampacked.core.packing_json as packing_json

    def full(*_args, **_kwargs):
        raise OSError(28, "No space left on device")

    if failing == "save_packing":  # the file system under the packing's atomic write
        monkeypatch.setattr(packing_json, "_atomic_write_text", full)
    else:
        monkeypatch.setattr(preview_module, failing, full)
    out, png = tmp_path / "p.json", tmp_path / "p.png"
    rc = main(["pack", *BRIEF, "-q", "-o", str(out), "--preview", str(png)])
    err = " ".join(capsys.readouterr().err.split())
    assert rc == 1 and "Traceback" not in err
    what, path = (("the packing", out) if failing == "save_packing" else ("the preview", png))
    assert f"cannot write {what} '{path}' (No space left on device)" in err, err
    if failing == "save_packing":
        assert "nothing was written there" in err and not out.exists()
    else:
        assert f"the packing was saved to '{out}'" in err and load_packing(out).n > 0


def test_terminated_after_the_packing_is_saved_says_so(tmp_path, monkeypatch, capsys):
    """SIGTERM while the preview was drawn: the packing was already saved, but the run
    said only "terminated"."""
    import jampacked.cli.preview as preview_module

    def terminated(*_args, **_kwargs):
        signal.raise_signal(signal.SIGTERM)

    monkeypatch.setattr(preview_module, "write_preview", terminated)
    out, png = tmp_path / "p.json", tmp_path / "p.png"
    rc = main(["pack", *BRIEF, "-q", "-o", str(out), "--preview", str(png)])
    err = " ".join(capsys.readouterr().err.split())
    assert rc == 128 + signal.SIGTERM
    assert f"terminated after the packing was saved to {out}; the preview {png} was not " \
        "written" in err, err
    assert err.endswith("was not written"), err  # said once (main said "terminated" again)
    assert load_packing(out).n > 0 and not png.exists()


def test_ctrl_c_while_the_engine_is_imported_stops_cleanly(tmp_path):
    """A Ctrl-C in the first second (the imports) stops the command with status 130 and no
    traceback; it was swallowed by an import (the run went on) or printed one."""
    out = tmp_path / "p.json"
    code = (
        "import builtins, signal, sys\n"
        "from jampacked.cli.main import main\n"
        "real = builtins.__import__\n"
        "def hooked(name, *a, **k):\n"
        "    if name == 'jampacked.cli.parser':\n"
        "        signal.raise_signal(signal.SIGINT)\n"
        "    return real(name, *a, **k)\n"
        "builtins.__import__ = hooked\n"
        f"sys.exit(main(['pack', 'box:30x30x30', '--type', {str(P1)!r}, '--fidelity', 'low', "
        f"'--time-budget', '2', '-q', '-o', {str(out)!r}]))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 130, proc.stderr
    assert "Traceback" not in proc.stderr and "interrupted" in proc.stderr
    assert not out.exists()


def test_pack_refuses_a_mesh_or_odd_image_name_for_its_outputs(tmp_path, capsys):
    """`pack -o p.stl` wrote JSON into a .stl file (which slicers then fail to read), and
    --preview p.jpg a PNG under a JPEG name; a folder given as a type said only 'not a
    file'."""
    for argv, words in (
            (["-o", str(tmp_path / "p.stl")], ["JSON", ".json", "jampacked export"]),
            (["-o", str(tmp_path / "p.json"), "--preview", str(tmp_path / "p.jpg")],
             ["PNG", ".png"])):
        rc = main(["pack", "box:30x30x30", "--type", str(P1), *SMALL, "-q", *argv])
        err = " ".join(capsys.readouterr().err.split())
        assert rc == 2 and all(w in err for w in words), err
    rc = main(["pack", "box:30x30x30", "--type", str(P1.parent), *SMALL, "-q", "-o",
               str(tmp_path / "p.json")])
    err = " ".join(capsys.readouterr().err.split())
    assert rc == 2 and "is a folder" in err and "one --type per file" in err
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------- bad input


@pytest.fixture
def not_a_mesh(tmp_path):
    f = tmp_path / "notes.txt"
    f.write_text("this is not a mesh\n")
    return f


@pytest.mark.parametrize(
    "argv, code, words",
    [
        (["box:30x30x30", "--type", "no_such_file.obj"], 2, ["no_such_file.obj", "not exist"]),
        (["no_such_container.stl", "--type", str(P1)], 2, ["no_such_container.stl"]),
        (["box:30x30x30", "--type", f"{P1}=lots"], 2, ["share", "lots"]),
        (["box:30x30x30", "--type", f"{P1}=-0.2"], 2, ["share", "-0.2"]),
        (["box:30x30x30", "--type", f"{P1}=70%", "--type", f"{P3}=0.5", "--type", str(P1)], 2,
         ["120%"]),
        (["box:0x1x1", "--type", str(P1)], 2, ["box:0x1x1"]),
        (["box:30x30", "--type", str(P1)], 2, ["box:30x30"]),
        (["box:30x30x30"], 2, ["--type"]),
        (["NOTAMESH", "--type", str(P1)], 1, ["notes.txt", "file type"]),
        (["box:30x30x30", "--type", "NOTAMESH"], 1, ["notes.txt", "file type"]),
        (["box:3x3x3", "--type", str(P1)], 1, ["no object fits"]),
    ],
)
def test_bad_input_exits_with_message(argv, code, words, tmp_path, not_a_mesh, capsys):
    argv = [str(not_a_mesh) if a == "NOTAMESH" else a for a in argv]
    rc = main(["pack", *argv, *SMALL, "-q", "-o", str(tmp_path / "p.json")])
    err = capsys.readouterr().err
    assert rc == code, err
    assert err.startswith("error: ") and err.count("\n") == 1, err  # one line, no traceback
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "p.json").exists()


def test_missing_output_folder(tmp_path, capsys):
    out = tmp_path / "nope" / "p.json"
    assert main(["pack", "box:30x30x30", "--type", str(P1), "-o", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    # a file where the folder should be was "folder ... does not exist; create it first"
    (tmp_path / "afile").write_text("x")
    for argv in (["pack", "box:30x30x30", "--type", str(P1), "-o",
                  str(tmp_path / "afile" / "sub" / "p.json")],
                 ["pack", "box:30x30x30", "--type", str(P1), "-o", str(tmp_path / "p.json"),
                  "--preview", str(tmp_path / "afile" / "p.png")]):
        assert main(argv) == 2
        err = " ".join(capsys.readouterr().err.split())
        assert f"'{tmp_path / 'afile'}' is a file, not a folder" in err, err
    # an empty name was "-o  is a folder"
    assert main(["pack", "box:30x30x30", "--type", str(P1), "-o", ""]) == 2
    assert "-o is empty: give a file name" in capsys.readouterr().err


def test_bad_numbers_are_usage_errors(tmp_path, capsys):
    rc = main(["pack", "box:30x30x30", "--type", str(P1), "--clearance", "-1",
               "-o", str(tmp_path / "p.json")])
    assert rc == 2 and "--clearance" in capsys.readouterr().err
    rc = main(["pack", "box:30x30x30", "--type", str(P1), "--mix-tolerance", "1.5",
               "-o", str(tmp_path / "p.json")])
    err = capsys.readouterr().err
    assert rc == 2 and "--mix-tolerance" in err and "from 0 to 1" in err
    assert not (tmp_path / "p.json").exists()
    # argparse names the option; the message repeated it ("argument --container-size:
    # --container-size must be greater than 0")
    for option, value, words in (("--container-size", "0", "must be a finite number greater "
                                  "than 0"), ("--attempts", "0", "must be 1 or more"),
                                 ("--time-budget", "x", "must be a number"),
                                 ("--time-budget", "inf", "must be a finite number greater "
                                  "than 0"),
                                 # inf was "must be 0 or more"
                                 ("--clearance", "inf", "must be a finite number, 0 or more")):
        rc = main(["pack", "box:30x30x30", "--type", str(P1), option, value,
                   "-o", str(tmp_path / "p.json")])
        err = capsys.readouterr().err
        assert rc == 2 and f"argument {option}: {words}, got '{value}'" in err, err
        assert err.splitlines()[-1].count(option) == 1, err


def test_export_openings_name_their_option_once(tmp_path, capsys):
    # "argument --open-plane: --open-plane: the axis must be ...": argparse names the
    # option before the message of a type function, which named it again
    for option, value, words in (("--open-plane", "+q@0.5", "the axis must be one of"),
                                 ("--window", "+y", "give AXIS@SIZE"),
                                 ("--window", "+y@abc", "'abc' is not a number")):
        rc = main(["export", str(tmp_path / "p.json"), "--shell", "1", option, value,
                   "-o", str(tmp_path / "x.3mf")])
        err = capsys.readouterr().err
        assert rc == 2 and f"argument {option}: {words}" in err, err
        assert err.splitlines()[-1].count(option) == 1, err
    assert not (tmp_path / "x.3mf").exists()


def test_mix_tolerance_reaches_the_late_passes(tmp_path):
    """--mix-tolerance sets the cap the extra cavity passes keep the type mix error under;
    the packing file records it."""
    out = tmp_path / "p.json"
    rc, _, se = run(["pack", "box:30x30x30", "--type", str(P1), "--type", str(P3),
                     "--fidelity", "low", "--time-budget", "1", "--seed", "1",
                     "--mix-tolerance", "0.01", "-q", "-o", str(out)])
    assert rc == 0, se
    assert load_packing(out).inputs.options.cavity.max_tvd == 0.01


def test_info_on_a_non_packing(not_a_mesh, capsys):
    assert main(["info", str(not_a_mesh)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "notes.txt" in err


def test_debug_shows_traceback(not_a_mesh):
    with pytest.raises(InputError):
        main(["--debug", "info", str(not_a_mesh)])


# --------------------------------------------------------------------------- parsing, help


@pytest.mark.parametrize("text, expected", [
    ("a.obj", ("a.obj", None)), ("a.obj=0.4", ("a.obj", 0.4)), ("a.obj=40%", ("a.obj", 0.4)),
    ("a.obj=2", ("a.obj", 2.0)), ("dir/a b.stl=12.5 %", ("dir/a b.stl", 0.125)),
])
def test_parse_type_arg(text, expected):
    path, share = parse_type_arg(text)
    assert path == expected[0]
    assert share == (None if expected[1] is None else pytest.approx(expected[1]))


def test_resolve_shares():
    assert resolve_shares([None, None], ["a", "b"]) is None
    assert resolve_shares([2.0, 1.0], ["a", "b"]) == [2.0, 1.0]
    assert resolve_shares([0.4, None, None], ["a", "b", "c"]) == pytest.approx([0.4, 0.3, 0.3])
    with pytest.raises(UsageError, match="100%"):
        resolve_shares([0.6, 0.4, None], ["a", "b", "c"])


def test_shares_note_when_percents_do_not_add_up():
    assert shares_note(None, ["a"]) is None
    assert shares_note([0.4, 0.6], ["a", "b"]) is None
    assert shares_note([1 / 3, 1 / 3, 0.333], ["a", "b", "c"]) is None  # rounding
    assert shares_note([2.0, 1.0], ["a", "b"]) is None  # weights: proportions meant
    note = shares_note([0.4, 0.4, 0.4], ["a", "b", "c"])
    assert note is not None and "120%" in note and "a 33.3%, b 33.3%, c 33.3%" in note
    assert "60%" in shares_note([0.3, 0.3], ["a", "b"])
    # 50% and 30% are 62.5% and 37.5% (whole percents read 62% and 37%: 99%)
    assert shares_note([0.5, 0.3], ["a", "b"]).endswith("a 62.5%, b 37.5%")
    # small shares read "add up to 0%"
    assert "add up to 0.5%, not 100%" in shares_note([0.003, 0.002], ["a", "b"])


def test_pack_warns_when_percents_do_not_add_up(tmp_path):
    out = tmp_path / "p.json"
    rc, _, se = run(["pack", "box:30x30x30", "--type", f"{P1}=30%", "--type", f"{P3}=30%",
                     "--fidelity", "low", "--time-budget", "1", "--seed", "1", "-q",
                     "-o", str(out)])
    assert rc == 0, se
    assert "warning:" in se and "add up to 60%" in se and "polytope1 50%" in se
    assert [t.share for t in load_packing(out).types] == pytest.approx([0.5, 0.5])
    rc, _, se = run(["pack", "box:30x30x30", "--type", f"{P1}=40%", "--type", f"{P3}=60%",
                     "--fidelity", "low", "--time-budget", "1", "--seed", "1", "-q",
                     "-o", str(out)])
    assert rc == 0 and "add up" not in se


def test_one_file_given_as_two_types_is_said_with_the_names_they_get(tmp_path):
    """The same polytope twice (60% and 20%) packed as two types without a word, and the
    shares' note named both "polytope1"."""
    args = build_parser().parse_args(["pack", "box:30x30x30", "--type", f"{P1}=60%",
                                      "--type", f"{P1}=20%", "--type", f"{P3}=30%",
                                      "-o", str(tmp_path / "p.json")])
    with contextlib.ExitStack() as stack:
        scene = resolve_scene(args, stack)
    twice, shares = scene.notes
    assert "given more than once" in twice and "as polytope1, polytope1-2" in twice
    assert "give it once (with the sum of their shares, if given)" in twice
    # the same file through a link is the same file
    link = tmp_path / "again.obj"
    link.symlink_to(P1)
    args = build_parser().parse_args(["pack", "box:30x30x30", "--type", str(P1), "--type",
                                      str(link), "-o", str(tmp_path / "p.json")])
    with contextlib.ExitStack() as stack:
        (note,) = resolve_scene(args, stack).notes
    assert f"{P1} and {link} as polytope1, again" in note
    assert shares.endswith("polytope1 54.5%, polytope1-2 18.2%, polytope3 27.3%")
    args = build_parser().parse_args(["pack", "box:30x30x30", "--type", str(P1), "--type",
                                      str(P3), "-o", str(tmp_path / "p.json")])
    with contextlib.ExitStack() as stack:
        assert resolve_scene(args, stack).notes == []


def test_default_scene_resolves_bundled_files(tmp_path):
    args = build_parser().parse_args(["pack", "default", "-o", str(tmp_path / "p.json")])
    with contextlib.ExitStack() as stack:
        scene = resolve_scene(args, stack)
        assert os.path.isfile(scene.container) and scene.container.endswith("spot.obj")
        assert len(scene.types) == 5 and all(os.path.isfile(t) for t in scene.types)
    assert scene.names == ["banana", "strawberry", "lemon", "peach", "orange"]
    assert scene.shares is None
    assert (scene.container_size, scene.type_scale) == (150.0, 300.0)
    args = build_parser().parse_args(["pack", "default", "--container-size", "90",
                                          "--type", str(P1), "-o", str(tmp_path / "p.json")])
    with contextlib.ExitStack() as stack:
        scene = resolve_scene(args, stack)
    assert scene.types == [str(P1)] and scene.names is None
    assert (scene.container_size, scene.type_scale) == (90.0, 1.0)


def test_help(capsys):
    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    assert "pack" in text and "info" in text and "examples:" in text
    assert main(["pack", "--help"]) == 0
    text = capsys.readouterr().out
    for word in ("--type", "SHARE", "--clearance", "container units", "examples:", "mm"):
        assert word in text, word
    # argparse expands %% in options' help only, not in the descriptions and epilogs
    for command in ("pack", "export", "info", "validate", "batch"):
        assert main([command, "--help"]) == 0
        assert "%%" not in capsys.readouterr().out, command
    assert main([]) == 2  # a command is required


def test_python_dash_m(tmp_path):
    env = dict(os.environ)
    shim = [p for p in sys.path if p and (Path(p) / "jampacked").is_dir()]
    env["PYTHONPATH"] = os.pathsep.join(shim + [env.get("PYTHONPATH", "")])
    r = subprocess.run([sys.executable, "-m", "jampacked.cli.main", "--help"], env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "jampacked" in r.stdout


# --------------------------------------------------------------------------- first run


def test_a_cold_engine_cache_is_told_apart_from_a_warm_one(tmp_path):
    """numba's cache of the placement kernels: cold in an empty NUMBA_CACHE_DIR (a first
    run compiles), warm here where the kernels have run (a fixture packed). Reads index
    files only: nothing compiles."""
    code = "from jampacked.core.numba_cache import cache_is_cold; print(cache_is_cold())"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty")}
    cold = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, timeout=120)
    assert cold.stdout.strip() == "True", cold.stderr
    warm = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, env={k: v for k, v in os.environ.items()
                                            if k != "NUMBA_CACHE_DIR"})
    assert warm.stdout.strip() == "False", warm.stderr


def test_pack_says_it_compiles_before_the_budget_and_notes_a_slow_compile(tmp_path,
                                                                          monkeypatch):
    """With a cold cache pack() reports the compile step before phase 1 (the budget starts
    after it); a compile that took long gets a note on stderr saying where it is cached."""
    from jampacked.core import api, numba_cache
    from jampacked.core.numba_cache import COMPILE_MESSAGE

    messages = []

    def placing() -> bool:  # the messages asked about all come before placement starts:
        return any(m.startswith("phase 1") for m in messages)  # stop there, as a Ctrl-C

    monkeypatch.setattr(api, "cache_is_cold", lambda: True)
    api.pack("box:30x30x30", [str(P1)], fidelity="low", seed=1,
             progress=lambda f, m: messages.append(m), should_cancel=placing)
    assert COMPILE_MESSAGE in messages
    assert messages.index(COMPILE_MESSAGE) < min(
        i for i, m in enumerate(messages) if m.startswith("phase 1"))
    monkeypatch.setattr(api, "cache_is_cold", lambda: False)
    messages.clear()
    api.pack("box:30x30x30", [str(P1)], fidelity="low", seed=1,
             progress=lambda f, m: messages.append(m), should_cancel=placing)
    assert placing()  # the warm run got as far as placement
    assert COMPILE_MESSAGE not in messages

    monkeypatch.setattr(numba_cache, "SLOW_WARM_UP", 0.0)  # any compile time counts as slow
    rc, _, se = run(["pack", *BRIEF, "-o", str(tmp_path / "p.json")])
    assert rc == 0, se
    assert "compiling the engine took" in se and "first run only" in se


# --------------------------------------------------------------------------- render


def _box(size: float, inward: bool = False) -> tuple[np.ndarray, np.ndarray]:
    from jampacked.core.meshes import box_mesh

    m = box_mesh([size] * 3)
    faces = np.asarray(m.faces)
    return np.asarray(m.vertices, np.float64), faces[:, ::-1] if inward else faces


def _hollow_box_with_a_cube_inside(fused: bool) -> tuple[np.ndarray, np.ndarray]:
    """A 2-unit shell around a 20-unit cavity, a 6-unit cube inside (touching the shell's
    inner wall through one shared vertex when ``fused``, as connect mode joins them)."""
    parts = [_box(24.0), _box(20.0, inward=True), _box(6.0)]
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(f + base)
        base += len(v)
    v, f = np.concatenate(verts), np.concatenate(faces)
    if fused:  # one body: a sliver triangle from the cube to a corner of the inner wall
        f = np.vstack([f, [[16 + 7, 16 + 6, 8 + 7]]])
    return v, f


def _coloured_pixels(png: Path) -> tuple[int, int]:
    """Pixels in colour (the packed objects; the shell and the page are grey or white) in
    the left and right halves of a render."""
    import matplotlib.image as mpimg

    img = mpimg.imread(png)[..., :3]
    warm = img.max(axis=2) - img.min(axis=2) > 0.2
    half = img.shape[1] // 2
    return int(warm[:, :half].sum()), int(warm[:, half:].sum())


@pytest.mark.parametrize("fused", [False, True])
def test_render_cuts_the_shell_open_so_the_packed_objects_show(tmp_path, fused):
    """The render is lit (shades vary across the shell) and its right view cuts the shell's
    near half away: the cube inside shows there and not in the closed view. A shell fused
    to the objects (one body) is told apart by the container (the cavity's surface)."""
    from jampacked.cli import render

    v, f = _hollow_box_with_a_cube_inside(fused)
    body = render.bodies(f, len(v))
    assert len(np.unique(body)) == (2 if fused else 3)  # outer wall, inner wall, cube
    if not fused:
        shell = render.shell_bodies(v[f], body)
        assert sorted(shell.tolist()) == [0, 1]
    container = _box(20.0) if fused else None
    out = tmp_path / "render.png"
    render.write_render(v, f, out, up="+z", container=container)
    left, right = _coloured_pixels(out)
    assert left == 0 and right > 500, (left, right)


def test_outputs_in_a_folder_that_takes_no_file_are_refused_before_packing(
        packed, read_only_folder, monkeypatch):
    # pack -o into a read-only folder packed for 22 s and then ended in a traceback,
    # losing the packing; --preview likewise, and export found it after building
    from jampacked.core import api

    def no_packing(*_a, **_k):
        raise AssertionError("packed although the output cannot be written")

    monkeypatch.setattr(api, "pack", no_packing)
    read_only = read_only_folder
    for argv in (["-o", str(read_only / "p.json")],
                 ["-o", str(packed[1].parent / "elsewhere.json"),
                  "--preview", str(read_only / "p.png")]):
        rc, _, se = run(["pack", "box:30x30x30", "--type", str(P1), *SMALL, *argv])
        assert rc == 2 and "Read-only file system" in se and "chmod" in se, se
    rc, _, se = run(["export", str(packed[1]), "-o", str(read_only / "x.3mf")])
    assert rc == 2 and "Read-only file system" in se, se
    assert not list(read_only.iterdir())


def test_outputs_that_are_inputs_are_refused_and_left_alone(packed, tmp_path):
    # pack -o onto a type mesh and export -o onto its packing: exit 2 naming the input,
    # which is left as it was
    d, out, *_ = packed
    mesh = tmp_path / "p1.obj"
    mesh.write_bytes(P1.read_bytes())
    before_mesh, before_packing = mesh.read_bytes(), out.read_bytes()
    rc, _, se = run(["pack", "box:30x30x30", "--type", str(mesh), *SMALL, "-o", str(mesh)])
    assert rc == 2 and "is the input mesh" in se and mesh.read_bytes() == before_mesh
    rc, _, se = run(["export", str(out), "-o", str(out)])
    assert rc == 2 and "is the packing file" in se and out.read_bytes() == before_packing
    # export -o onto a type mesh the packing names, a file named twice, an unknown format:
    # usage errors too (exit 2), as pack's are; they exited 1
    moved = json.loads(out.read_text())
    moved["types"][0]["path"] = str(mesh)
    relinked = tmp_path / "relinked.json"
    relinked.write_text(json.dumps(moved))
    rc, _, se = run(["export", str(relinked), "-o", str(mesh)])
    assert rc == 2 and "it is an input file" in se and mesh.read_bytes() == before_mesh
    a_stl = tmp_path / "a.stl"
    rc, _, se = run(["export", str(out), "-o", str(a_stl), "-o", f"{tmp_path}/./a.stl"])
    assert rc == 2 and "named twice" in se and not a_stl.exists()
    rc, _, se = run(["export", str(out), "-o", str(tmp_path / "a.xyz")])
    assert rc == 2 and "unknown mesh format '.xyz'" in se


def test_export_json_prints_a_document_when_it_fails(packed, tmp_path):
    # a failed `export --json` printed nothing on stdout, only the error line on stderr
    _, out, *_ = packed
    rc, so, se = run(["export", str(out), "--mode", "parts", "--json", "-o",
                      str(tmp_path / "p.3mf")])  # parts need a clearance: this packing has none
    doc = json.loads(so)
    assert rc == 1 and doc["passed"] is False and "needs a gap" in doc["error"]
    assert se.startswith("error: ") and not (tmp_path / "p.3mf").exists()
    rc, so, _ = run(["export", str(out), "--json", "-o", str(tmp_path / "p.xyz")])
    assert rc == 2 and "unknown mesh format" in json.loads(so)["error"]
    # refused by the command line's own checks before the export starts: JSON too
    rc, so, _ = run(["export", str(out), "--json", "-o", str(tmp_path / "nope" / "x.stl")])
    assert rc == 2 and "does not exist" in json.loads(so)["error"]


def test_info_on_a_mesh_file_says_it_is_a_mesh(capsys):
    """`info spot.obj` asked whether the file was truncated or edited."""
    assert main(["info", str(P1)]) == 1
    err = " ".join(capsys.readouterr().err.split())
    assert "mesh file, not a packing" in err and "jampacked validate" in err
    assert "truncated" not in err


def test_output_into_a_closed_pipe_ends_quietly():
    """`jampacked validate --json FILE | head` ended in a BrokenPipeError traceback."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from jampacked.cli.main import main; "
         "sys.exit(main())", "validate", "--json", str(P1)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before anything is written
    err = proc.stderr.read().decode()
    proc.wait(timeout=300)
    assert "Traceback" not in err and "BrokenPipe" not in err, err


def test_a_negative_axis_without_equals_says_how_to_write_it(capsys):
    """`--up -y` reads -y as an option; argparse said only 'expected one argument'."""
    assert main(["export", "p.json", "--up", "-y", "-o", "a.stl"]) == 2
    assert "--up=-y" in capsys.readouterr().err
    assert main(["pack", "box:9x9x9", "--type", str(P1), "-o"]) == 2
    assert "negative axis" not in capsys.readouterr().err  # a value simply missing


def test_ctrl_c_once_the_export_is_written_keeps_status_0(packed, tmp_path, monkeypatch,
                                                         capsys):
    """A Ctrl-C while the report was printed (the files already in place) ended the command
    with 130, as if the export had failed."""
    from jampacked.cli import export_cmd

    _, out, *_ = packed
    real = export_cmd.print_export

    def ctrl_c_then_print(*args, **kwargs):
        signal.raise_signal(signal.SIGINT)
        return real(*args, **kwargs)

    monkeypatch.setattr(export_cmd, "print_export", ctrl_c_then_print)
    # a 3MF: the packing (a budgeted run) changes with the machine's load, and an STL of a
    # union of touching objects can be refused for float32 rounding, which is not this test
    u = tmp_path / "u.3mf"
    assert main(["export", str(out), "--mode", "union", "-o", str(u)]) == 0
    assert "export was completed" in " ".join(capsys.readouterr().err.split())
    assert u.is_file()


def test_a_large_scene_without_a_budget_says_so_up_front(tmp_path, monkeypatch):
    # 22,000 oranges and lemons without a budget ran for 27 minutes with no word that the
    # cavity passes take hours at that size
    from jampacked.cli import interrupt, reports

    seen, placing, stop_there = [], [], [True]
    # stop as a Ctrl-C would once placement starts: the note must come before
    monkeypatch.setattr(interrupt.CancelOnInterrupt, "__call__",
                        lambda self: bool(placing) and stop_there[0])
    real = reports.progress_bar

    def bar(stack, err, cancel=None):
        update = real(stack, err, cancel)

        def spy(fraction, message):
            seen.extend([message] if message.startswith("note: ") else [])
            placing.extend([message] if message.startswith("phase") else [])
            update(fraction, message)
        return spy

    monkeypatch.setattr("jampacked.cli.pack_cmd.progress_bar", bar)
    ball = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=1, radius=1.0).export(ball)
    rc, _, err = run(["pack", "box:30x30x30", "--type", str(ball), "-o",
                      str(tmp_path / "p.json")])
    assert rc == 130 and len(seen) == 1
    assert "note: about 4," in err and "no time budget" in err and "--time-budget" in err
    seen.clear()
    stop_there[0] = False
    rc, _, err = run(["pack", "box:30x30x30", "--type", str(ball), "--time-budget", "0.5",
                      "-o", str(tmp_path / "p.json")])
    assert rc == 0 and not seen and "no time budget" not in err
    # quiet keeps warnings, and the note is one (stopped at once, as by a Ctrl-C)
    monkeypatch.setattr(interrupt.CancelOnInterrupt, "__call__", lambda self: True)
    rc, _, err = run(["pack", "box:30x30x30", "--type", str(ball), "-q", "-o",
                      str(tmp_path / "p.json")])
    assert rc == 130 and "note: about 4," in err
