"""`jampacked batch`: the batch file's checks (clear errors naming scene, line and key), a
local run with its summary table, and a rerun that skips what is done and verified."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import signal
import textwrap

import numpy as np
import pytest
from testdata import mesh_path

from jampacked.cli.main import main
from jampacked.core.batch import run_batch
from jampacked.core.batch_file import read_batch
from jampacked.core.errors import InputError
from jampacked.core.packing_json import load_packing

P1 = mesh_path("polyhedra/convex5/polytope1.obj")
P3 = mesh_path("polyhedra/convex5/polytope3.obj")


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture
def folder(tmp_path):
    shutil.copy(P1, tmp_path / "a.obj")
    shutil.copy(P3, tmp_path / "b.obj")
    return tmp_path


def write(folder, text: str):
    path = folder / "scenes.toml"
    path.write_text(textwrap.dedent(text))
    return path


GOOD = """\
    [defaults]
    fidelity = "low"

    [[scene]]
    name = "small"
    containers = ["box:16x15x14", "box:15x16x14"]
    types = ["a.obj", "b.obj"]
    shares = [0.5, 0.5]
    seeds = [1, 2]
    """


def test_a_scene_expands_to_containers_times_sets_times_seeds(folder):
    scenes = read_batch(write(folder, GOOD + """
    [[scene]]
    container = "box:20x20x20"
    type_sets = [["a.obj"], ["a.obj", "b.obj"]]
    seed = 4
    clearance = 0.2
    """))
    assert [s.id for s in scenes] == ["small-c1-s1", "small-c1-s2", "small-c2-s1",
                                      "small-c2-s2", "scene2-t1-s4", "scene2-t2-s4"]
    assert scenes[0].types == (str(folder / "a.obj"), str(folder / "b.obj"))
    assert scenes[0].fidelity == "low" and scenes[0].shares == (0.5, 0.5)
    assert scenes[5].clearance == 0.2 and scenes[5].fidelity == "low"


@pytest.mark.parametrize("text, match", [
    ("[[scene]\ncontainer = 1", r"not valid TOML: .*line 1"),
    ("title = 'x'\n", r"unknown top-level key 'title'"),
    ("[defaults]\nfidelity = 'low'\n", r"lists no scenes"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n\n[[scene]]\n"
     "container='box:9x9x9'\ntypes=['a.obj']\nseed=1\ncolour='red'\n",
     r"scene 2 \(line 6\): unknown key 'colour' on line 10; known: name, "),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['missing.obj']\nseed=1\n",
     r"scene 1 \(line 1\), types: mesh file 'missing.obj' not found"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseeds=[1, -2]\n",
     r"seeds must be whole numbers >= 0, got -2"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\n", r"'seed' \(or 'seeds', a list\) "
     "is missing"),
    # [scene] for [[scene]]: "lists no scenes"; a folder as a type: "not found"
    ("[scene]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n",
     r"a scene is written \[\[scene\]\], with two brackets"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['sub']\nseed=1\n",
     r"scene 1 \(line 1\), types: 'sub' is a folder \(.*sub\), not a mesh file"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj', 'b.obj']\nshares=[1]\nseed=1\n",
     r"'shares' has 1 values for 2 types"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\nfidelity='ultra'\n",
     r"'fidelity' must be auto, low, medium or high"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\ntime_budget=-3\n",
     r"'time_budget' must be a finite number > 0, got -3"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\ntime_budget=inf\n",
     r"'time_budget' must be a finite number > 0, got inf"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\nexport=['step']\n",
     r"'export' must be a list of formats from 3mf, stl, obj, ply, got \['step'\]"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseeds=[1, 2, 1]\n",
     r"scene 1 \(line 1\): seed 1 is listed twice in 'seeds'; list each seed once"),
    ("[[scene]]\nname='a b'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n\n[[scene]]\n"
     "name='a_b'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n",
     r"scene 2 \(line 7\): scene id 'a_b-s1' is also made by scene 1 \(line 1\); give the "
     r"scenes different names \(.*'a b' and 'a_b' are one name"),
    ("[[scene]]\nname='Jar'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n\n[[scene]]\n"
     "name='jar'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n",
     r"scene 2 \(line 7\): scene id 'jar-s1' differs from 'Jar-s1' of scene 1 \(line 1\) "
     "only in case"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\nexport=['stl', '3mf', 'stl']\n",
     r"scene 1 \(line 1\): 'export' lists 'stl' twice; list each format once"),
    (f"[[scene]]\nname='{'n' * 300}'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\n",
     r"scene 1 \(line 1\): 'name' is too long for a file name \(300 characters\); give a "
     "name of at most 197"),
    (f"[[scene]]\nname='x'\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed={'9' * 240}\n",
     r"scene 1 \(line 1\): seed 9{240} is too long for a file name \(240 digits\); give "
     "seeds of at most 197 digits"),
    (f"[[scene]]\ncontainer='box:9x9x9'\ntypes=['{'a' * 5000}.obj']\nseed=1\n",
     r"scene 1 \(line 1\), types: mesh file 'a{77}\.\.\.' cannot be looked up: .*Give a "
     "shorter path"),
    ("[[scene]]\ncontainer='box:20x20'\ntypes=['a.obj']\nseed=1\n",
     r"scenes.toml, scene 1 \(line 1\), container: box spec 'box:20x20' is malformed"),
    ("[defaults]\nexport=['stl']\nexport_mode='parts'\n\n[[scene]]\ncontainer='box:9x9x9'\n"
     "types=['a.obj']\nseed=1\n", r"scene 1 \(line 5\): export_mode = \"parts\" needs a gap "
     r"between the objects, but 'clearance' is 0.*clearance = 0.2 in this scene"),
    ("[[scene]]\ncontainer='box:9x9x9'\ntypes=['a.obj']\nseed=1\nclearance=0.2\n"
     "export=['stl']\nexport_mode='parts'\nexport_shell=1\n",
     r"scene 1 \(line 1\): export_mode = \"parts\" writes the objects only, and "
     "'export_shell' would trap them"),
])
def test_bad_batch_files_name_the_scene_line_and_key(folder, text, match):
    (folder / "sub").mkdir()
    path = write(folder, text)
    with pytest.raises(InputError, match=match):
        read_batch(path)
    rc, _, err = run(["batch", str(path), "-o", str(folder / "out"), "-q"])
    assert rc == 1 and "scenes.toml" in err


def test_batch_writes_each_packing_and_a_summary_and_a_rerun_skips_them(folder):
    path = write(folder, GOOD)
    out = folder / "out"
    rc, stdout, _ = run(["batch", str(path), "-o", str(out)])
    assert rc == 0 and "small-c2-s2" in stdout
    with open(out / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["packed"] * 4
    assert all(r["certified"] == "True" and int(r["count"]) > 0 for r in rows)
    assert {r["batch"] for r in rows} == {str(path.resolve())}
    assert sorted(p.name for p in out.glob("*.json")) == sorted(f"{r['id']}.json" for r in rows)

    before = (out / "small-c1-s1.json").read_bytes()
    rc, _, _ = run(["batch", str(path), "-o", str(out), "-q"])
    assert rc == 0
    with open(out / "summary.csv", newline="") as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["skipped"] * 4
    assert (out / "small-c1-s1.json").read_bytes() == before

    # a changed source mesh: its packings no longer verify and are made again
    with open(folder / "b.obj", "a") as f:
        f.write("# changed\n")
    rc, _, _ = run(["batch", str(path), "-o", str(out), "-q"])
    with open(out / "summary.csv", newline="") as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["packed"] * 4


def test_workers_and_scheduler_together_are_refused(folder):
    rc, _, err = run(["batch", str(write(folder, GOOD)), "-o", str(folder / "out"),
                      "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"])
    assert rc == 2 and "--workers or --scheduler" in err


def test_pack_attempts_on_local_workers_match_attempts_here(tmp_path):
    # the batch scenes' box (3 objects an attempt; 22x20x21 held 6 in three times the time)
    args = ["pack", "box:16x15x14", "--type", str(P1), "--type", str(P3), "--fidelity", "low",
            "--seed", "2", "--attempts", "2", "-q"]
    assert run([*args, "-o", str(tmp_path / "here.json")])[0] == 0
    assert run([*args, "-o", str(tmp_path / "there.json"), "--workers", "2"])[0] == 0
    here, there = (load_packing(tmp_path / f"{n}.json") for n in ("here", "there"))
    assert len(here.report.attempts) == len(there.report.attempts) == 2
    assert here.n > 0
    np.testing.assert_array_equal(here.translations, there.translations)
    np.testing.assert_array_equal(here.type_index, there.type_index)


def test_an_unreachable_scheduler_is_a_clear_error(folder, monkeypatch):
    from jampacked.core import cluster

    # nothing listens there: the connection is refused at once and retried until the
    # timeout (the product's 10 s), which only makes the test wait
    monkeypatch.setattr(cluster, "CONNECT_TIMEOUT", "1s")
    rc, _, err = run(["batch", str(write(folder, GOOD)), "-o", str(folder / "out"), "-q",
                      "--scheduler", "tcp://127.0.0.1:1"])
    assert rc == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:1" in err
    assert not (folder / "out").exists()


@pytest.mark.parametrize("address", ["127.0.0.1", "nonsense", "tcp://127.0.0.1:port"])
def test_a_scheduler_address_without_a_port_is_a_clear_error(folder, address):
    rc, _, err = run(["batch", str(write(folder, GOOD)), "-o", str(folder / "out"), "-q",
                      "--scheduler", address])
    assert rc == 1 and f"address {address!r} is not of the form tcp://HOST:PORT" in err
    assert not (folder / "out").exists()


#: one scene of the two polytopes, to which a test adds its export settings
ONE_SCENE = """\
[[scene]]
container = "box:16x15x14"
types = ["a.obj", "b.obj"]
seed = 1
fidelity = "low"
"""


def test_batch_exports_each_packing_and_a_rerun_makes_only_missing_files(folder):
    path = write(folder, ONE_SCENE + 'export = ["stl", "obj"]\nexport_mode = "union"\n')
    out = folder / "out"
    assert run(["batch", str(path), "-o", str(out), "-q"])[0] == 0
    stl = (out / "scene1-s1.stl").stat().st_mtime_ns
    assert (out / "scene1-s1.obj").is_file()
    (out / "scene1-s1.obj").unlink()
    assert run(["batch", str(path), "-o", str(out), "-q"])[0] == 0
    assert (out / "scene1-s1.obj").is_file() and (out / "scene1-s1.stl").stat().st_mtime_ns == stl
    with open(out / "summary.csv", newline="") as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["skipped"]


def test_an_exports_warnings_are_printed_and_kept_in_the_summary(folder):
    """A connect export with a closed shell that shuts in a void: `jampacked export` warns
    that resin and powder printers cannot drain it, where the batch said nothing (an
    independent check's print-farm scene). The warning is printed and in the summary's
    message column, on the run that exports and on a rerun that skips the scene."""
    path = write(folder, ONE_SCENE + 'export = ["stl"]\nexport_mode = "connect"\n'
                         'export_shell = 1.0\n')
    out = folder / "out"
    for status in ("packed", "skipped"):
        rc, _, err = run(["batch", str(path), "-o", str(out), "-q"])
        assert rc == 0
        said = " ".join(err.split())
        assert "warning: scene1-s1: export: the result encloses 1 sealed void" in said, said
        with open(out / "summary.csv", newline="") as f:
            [row] = list(csv.DictReader(f))
        assert row["status"] == status
        assert "export: the result encloses 1 sealed void" in row["message"]


def test_a_failed_export_keeps_the_warnings_of_the_files_kept(folder, monkeypatch):
    """A rerun's export of a missing file that fails leaves the earlier files and their
    record: their export's warnings stay recorded (they were written empty)."""
    from jampacked.core.errors import MeshError
    from jampacked.export import assemble

    path = write(folder, ONE_SCENE + 'export = ["stl", "obj"]\nexport_mode = "connect"\n'
                         'export_shell = 1.0\n')
    out = folder / "out"
    assert run(["batch", str(path), "-o", str(out), "-q"])[0] == 0
    record = out / "scene1-s1.exports.json"
    warned = json.loads(record.read_text())["warnings"]
    assert warned and "sealed void" in warned[0]
    (out / "scene1-s1.obj").unlink()

    def fail(*args, **kwargs):
        raise MeshError("made to fail by the test")

    monkeypatch.setattr(assemble, "export_packing", fail)
    assert run(["batch", str(path), "-o", str(out), "-q"])[0] == 1
    assert json.loads(record.read_text())["warnings"] == warned
    assert (out / "scene1-s1.stl").is_file()


#: one scene, 'v', which two batch files write in the tests below
SCENE_V = textwrap.dedent("""\
    [[scene]]
    name = "v"
    container = "box:16x15x14"
    types = ["a.obj", "b.obj"]
    seed = 1
    fidelity = "low"
    """)


def test_a_scene_another_batch_file_wrote_is_refused_before_any_work(folder):
    """Two batch files with a scene of the same id, one output folder: each run packed it
    again for its own container and replaced the other's packing and summary row, saying
    only that 'the earlier file was not trusted'. It is refused, naming the other file;
    once that file is gone the scene is this batch's."""
    first = folder / "first.toml"
    first.write_text(SCENE_V)
    other = folder / "other.toml"
    other.write_text(first.read_text().replace("box:16x15x14", "box:15x16x14"))
    out = folder / "out"
    assert run(["batch", str(first), "-o", str(out), "-q"])[0] == 0
    packed = (out / "v-s1.json").read_bytes()
    rc, _, err = run(["batch", str(other), "-o", str(out), "-q"])
    said = " ".join(err.split())
    assert rc == 1 and f"scene 'v-s1' in {out} was written by another batch file, {first}" \
        in said, said
    assert (out / "v-s1.json").read_bytes() == packed
    assert run(["batch", str(first), "-o", str(out), "-q"])[0] == 0  # its own: skipped
    # a copy of the project (its batch file and output elsewhere) is its own
    copy = folder / "copy"
    copy.mkdir()
    shutil.copytree(out, copy / "out")
    for name in ("first.toml", "a.obj", "b.obj"):
        shutil.copy(folder / name, copy / name)
    assert run(["batch", str(copy / "first.toml"), "-o", str(copy / "out"), "-q"])[0] == 0
    first.unlink()
    assert run(["batch", str(other), "-o", str(out), "-q"])[0] == 0
    assert (out / "v-s1.json").read_bytes() != packed


def test_a_scene_a_batch_file_in_another_folder_wrote_here_is_refused(folder):
    """Two batch files in different folders writing one scene id into one output folder
    replaced each other's packing on every run: only a batch file beside this one was
    caught (a copied project keeps rows naming its original's). The summary now records
    the folder each row was written in, which tells the two apart."""
    first = folder / "first.toml"
    first.write_text(SCENE_V.replace('"a.obj", "b.obj"', '"../a.obj", "../b.obj"'))
    (folder / "one").mkdir()
    (folder / "two").mkdir()
    first = first.rename(folder / "one" / "first.toml")
    other = folder / "two" / "other.toml"
    other.write_text(first.read_text().replace("box:16x15x14", "box:15x16x14"))
    out = folder / "shared-out"
    assert run(["batch", str(first), "-o", str(out), "-q"])[0] == 0
    packed = (out / "v-s1.json").read_bytes()
    rc, _, err = run(["batch", str(other), "-o", str(out), "-q"])
    said = " ".join(err.split())
    assert rc == 1 and f"was written by another batch file, {first}" in said, said
    assert (out / "v-s1.json").read_bytes() == packed


def test_outputs_that_would_replace_an_input_or_an_empty_folder_are_refused(folder):
    """A batch file named as a scene's packing (or as the summary) and run into its own
    folder was replaced by the packing, with exit 0; an empty -o wrote into the current
    folder. Both are refused before anything is packed."""
    text = textwrap.dedent(GOOD).replace('seeds = [1, 2]', 'seed = 1').replace(
        ', "box:15x16x14"', '')
    for name, what in (("small-s1.json", "scene small-s1"), ("summary.csv", "its summary")):
        path = folder / name
        path.write_text(text)
        rc, _, err = run(["batch", str(path), "-o", str(folder), "-q"])
        said = " ".join(err.split())
        assert rc == 1 and f"{path} is an input of the batch" in said and what in said, said
        assert path.read_text() == text
        path.unlink()
    # the same file by another name (a hard link; another case where the file system
    # ignores case) is the input too
    path = folder / "scenes.toml"
    path.write_text(text)
    os.link(path, folder / "small-s1.json")
    rc, _, err = run(["batch", str(path), "-o", str(folder), "-q"])
    assert rc == 1 and "small-s1.json is an input of the batch" in " ".join(err.split()), err
    (folder / "small-s1.json").unlink()
    # a mesh named as a scene's export
    (folder / "small-s1.stl").write_bytes((folder / "a.obj").read_bytes())
    path = write(folder, text.replace('"a.obj", "b.obj"', '"small-s1.obj", "b.obj"')
                 + 'export = ["obj"]\n')
    (folder / "small-s1.obj").write_bytes((folder / "a.obj").read_bytes())
    rc, _, err = run(["batch", str(path), "-o", str(folder), "-q"])
    assert rc == 1 and "small-s1.obj is an input of the batch" in " ".join(err.split()), err
    assert (folder / "small-s1.obj").read_bytes() == (folder / "a.obj").read_bytes()
    rc, _, err = run(["batch", str(path), "-o", "", "-q"])
    assert rc == 2 and "-o is empty" in err, err
    with pytest.raises(InputError, match=r"the output folder \(-o\) is empty"):
        run_batch(read_batch(path), "")


def test_a_rerun_with_nothing_to_do_starts_no_cluster(folder, monkeypatch):
    path = write(folder, GOOD.replace('seeds = [1, 2]', 'seeds = [1]').replace(
        ', "box:15x16x14"', ''))
    out = folder / "out"
    assert run(["batch", str(path), "-o", str(out), "-q"])[0] == 0
    import jampacked.core.cluster as cluster

    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started with nothing to run")

    monkeypatch.setattr(cluster, "client_for", no_cluster)
    assert run(["batch", str(path), "-o", str(out), "-q", "--workers", "2"])[0] == 0
    with open(out / "summary.csv", newline="") as f:
        assert [r["status"] for r in csv.DictReader(f)] == ["skipped"]


def _read_only(path):
    """Make the folder refuse new files (chmod, or chattr +i where the tests run as root,
    whom permissions do not stop); returns the undo, or None where neither works."""
    import os
    import subprocess

    path.chmod(0o555)
    if not os.access(path, os.W_OK):
        return lambda: path.chmod(0o755)
    path.chmod(0o755)
    if shutil.which("chattr") and subprocess.run(["chattr", "+i", str(path)],
                                                 capture_output=True).returncode == 0:
        return lambda: subprocess.run(["chattr", "-i", str(path)], check=True)
    return None


def test_an_output_folder_that_refuses_files_is_refused_before_packing(folder, monkeypatch):
    from jampacked.core import batch

    def no_packing(*a, **k):
        raise AssertionError("a scene was packed")

    monkeypatch.setattr(batch, "pack_scene", no_packing)
    out = folder / "out"
    out.mkdir()
    undo = _read_only(out)
    if undo is None:
        pytest.skip("no way to make a folder read-only here")
    try:
        rc, _, err = run(["batch", str(write(folder, GOOD)), "-o", str(out), "-q"])
        rc_sub, _, err_sub = run(["batch", str(write(folder, GOOD)), "-o", str(out / "sub"),
                                  "-q"])
    finally:
        undo()
    assert rc == 1 and f"cannot write in output folder {out}" in err and "-o" in err
    assert rc_sub == 1 and f"{out} is not writable" in err_sub
    assert "Traceback" not in err + err_sub


@pytest.mark.parametrize("name, what", [("small-c2-s1.json", "scene small-c2-s1"),
                                        ("summary.csv", "its summary")])
def test_a_folder_in_place_of_an_output_file_is_refused_before_packing(folder, monkeypatch,
                                                                        name, what):
    from jampacked.core import batch

    def no_packing(*a, **k):
        raise AssertionError("a scene was packed")

    monkeypatch.setattr(batch, "pack_scene", no_packing)
    (folder / "out" / name).mkdir(parents=True)
    rc, _, err = run(["batch", str(write(folder, GOOD)), "-o", str(folder / "out"), "-q"])
    assert rc == 1 and f"{folder / 'out' / name} is a folder" in err and what in err
    assert sorted(p.name for p in (folder / "out").iterdir()) == [name]


@pytest.mark.parametrize("name, scene_id", [("../escaped", "escaped-s1"),
                                            (".hidden", "hidden-s1"),
                                            ("-dash", "dash-s1"),
                                            ("a b/c", "a_b_c-s1")])
def test_scene_names_make_plain_visible_file_names(folder, name, scene_id):
    [spec] = read_batch(write(folder, f"[[scene]]\nname = {name!r}\ncontainer = 'box:9x9x9'\n"
                                      "types = ['a.obj']\nseed = 1\n"))
    assert spec.id == scene_id


def test_a_batch_file_saved_with_a_byte_order_mark_reads(folder):
    path = folder / "scenes.toml"
    path.write_text("[[scene]]\ncontainer = 'box:9x9x9'\ntypes = ['a.obj']\nseed = 1\n",
                    encoding="utf-8-sig")
    assert [s.id for s in read_batch(path)] == ["scene1-s1"]


def test_a_name_with_no_letter_or_digit_is_refused(folder):
    with pytest.raises(InputError, match=r"'name' must be a string with a letter or digit"):
        read_batch(write(folder, "[[scene]]\nname = '../'\ncontainer = 'box:9x9x9'\n"
                                 "types = ['a.obj']\nseed = 1\n"))


def test_a_rerun_exports_again_what_changed_settings_or_no_longer_matches(folder):
    scene = ONE_SCENE + 'export = ["stl", "obj"]\nexport_mode = "{mode}"\n'
    out = folder / "out"
    stl, obj = out / "scene1-s1.stl", out / "scene1-s1.obj"

    def rerun(mode: str) -> tuple[str, dict]:
        rc, _, err = run(["batch", str(write(folder, scene.format(mode=mode))), "-o",
                          str(out), "-q"])
        assert rc == 0
        with open(out / "summary.csv", newline="") as f:
            [row] = csv.DictReader(f)
        assert row["status"] in ("packed", "skipped")
        return err, row

    rerun("union")
    union = stl.read_bytes()
    err, row = rerun("connect")  # another export_mode: both files made again
    assert "scene1-s1.stl: made with export_mode 'union' -> 'connect'" in err
    assert "exported again" in row["message"] and row["status"] == "skipped"
    connect = stl.read_bytes()
    assert connect != union
    stl.write_bytes(connect[:100])  # a truncated file is made again, the other kept
    before = obj.stat().st_mtime_ns
    err, _ = rerun("connect")
    assert "scene1-s1.stl: changed since it was written" in err
    assert stl.read_bytes() == connect and obj.stat().st_mtime_ns == before
    err, row = rerun("connect")  # nothing left to do
    assert "exported again" not in err + row["message"]
    (out / "scene1-s1.exports.json").unlink()  # files without a record are not trusted
    err, _ = rerun("connect")
    assert "scene1-s1.obj: no record of how it was made" in err


def test_ctrl_c_writes_the_scene_packing_here_and_a_rerun_packs_it_again(folder, monkeypatch):
    from jampacked.core import batch

    real_pack = batch.pack

    def interrupted_pack(*args, should_cancel, **kwargs):
        polls = iter(range(10**9))

        def ctrl_c_once_objects_are_placed() -> bool:
            if next(polls) == 300:
                signal.raise_signal(signal.SIGINT)  # what Ctrl-C does
            return should_cancel()

        return real_pack(*args, should_cancel=ctrl_c_once_objects_are_placed, **kwargs)

    monkeypatch.setattr(batch, "pack", interrupted_pack)
    path = write(folder, "[[scene]]\nname = 'x'\ncontainer = 'box:30x30x30'\n"
                         "types = ['a.obj']\nseed = 1\nfidelity = 'low'\n")
    rc, _, err = run(["batch", str(path), "-o", str(folder / "out"), "-q"])
    assert rc == 130
    assert "note: x-s1: stopped by Ctrl-C before the end: its best certified packing so far " \
        "is written" in " ".join(err.split())
    p = load_packing(folder / "out" / "x-s1.json")
    assert p.n > 0 and p.report.stopped == "cancelled" and p.certificate["certified"] is True
    monkeypatch.undo()
    rc, _, err = run(["batch", str(path), "-o", str(folder / "out"), "-q"])
    assert rc == 0 and "x-s1 packed again: the earlier file was not trusted: stopped by " \
        "Ctrl-C before the end" in " ".join(err.split())
