"""`jampacked batch` reruns: a packing file is skipped only when its placements are the
ones that were certified and its numbers follow from them; anything else is packed again,
saying why. Also: each scene's run warnings reach the user (printed and in the CSV)."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import shutil
from dataclasses import replace

import pytest
from testdata import mesh_path

from jampacked.cli.main import main
from jampacked.core import batch
from jampacked.core.batch import DIGEST, check_done, run_batch, scene_file
from jampacked.core.batch_file import SceneSpec
from jampacked.core.packing_json import load_packing

P1 = str(mesh_path("polyhedra/convex5/polytope1.obj"))
P3 = str(mesh_path("polyhedra/convex5/polytope3.obj"))
SPEC = SceneSpec(id="x-s2", container="box:24x24x24", types=(P1, P3), seed=2,
                 fidelity="low")


@pytest.fixture(scope="module")
def packed(tmp_path_factory):
    out = tmp_path_factory.mktemp("packed")
    [r] = run_batch([SPEC], out)
    assert r.status == "packed" and r.packing.n >= 3
    return scene_file(out, SPEC)


@pytest.fixture
def copy(packed, tmp_path):
    path = scene_file(tmp_path, SPEC)
    shutil.copy(packed, path)
    return path


def edit(path, change) -> None:
    doc = json.loads(path.read_text())
    change(doc)
    for p in doc["placements"]:  # the redundant matrix follows its translation
        for i in range(3):
            p["matrix"][i][3] = p["translation"][i]
    path.write_text(json.dumps(doc))


def test_an_untouched_file_is_verified_and_records_a_digest(copy):
    done, why = check_done(SPEC, copy)
    assert done is not None and why == ""
    assert isinstance(done.certificate[DIGEST], str)


def _same_place(d):
    d["placements"][1]["translation"] = list(d["placements"][0]["translation"])


def _far_away(d):
    d["placements"][0]["translation"][0] += 500.0


def _density(d):
    d["metrics"]["density"] = 0.99


def _cut(d):
    d["placements"] = d["placements"][:2]


def _count_only(d):
    d["metrics"]["count"] += 1


def _no_digest(d):
    del d["certificate"][DIGEST]


def _turned_certified(d):
    d["certificate"]["worst_overlap"] = 0.0


@pytest.mark.parametrize("change, reason", [
    (_same_place, "changed after it was certified"),
    (_far_away, "changed after it was certified"),
    (_cut, "changed after it was certified"),
    (_turned_certified, "changed after it was certified"),
    (_density, "metrics.density reads 0.99 but its placements give"),
    (_count_only, "metrics.count reads"),
    (_no_digest, "records no digest of the certified placements"),
])
def test_an_edited_file_is_not_trusted(copy, change, reason):
    edit(copy, change)
    done, why = check_done(SPEC, copy)
    assert done is None and reason in why


def test_a_clearance_edited_to_the_batch_files_new_one_is_packed_again(copy):
    # the digest does not cover the clearance asked: a file whose inputs were edited to
    # the clearance the batch file now asks was skipped, certified for none
    edit(copy, lambda d: d["inputs"].update(clearance=0.5))
    done, why = check_done(replace(SPEC, clearance=0.5), copy)
    assert done is None and why == "it asks a clearance of 0.5, but was certified with 0", why


@pytest.mark.parametrize("shares", [(0.5, 0.5), None])
def test_a_file_made_with_other_shares_is_packed_again(packed, tmp_path, shares):
    # the batch file's shares changed, or were dropped (pack() then gives equal ones)
    spec = dataclasses.replace(SPEC, shares=(0.8, 0.2))
    [r] = run_batch([spec], tmp_path)
    assert r.status == "packed"
    assert check_done(spec, scene_file(tmp_path, spec))[0] is not None
    done, why = check_done(dataclasses.replace(SPEC, shares=shares),
                           scene_file(tmp_path, spec))
    assert done is None and why == "made with a different 'shares'"


def test_a_verified_file_with_unreadable_timings_is_skipped_and_summarised(copy):
    # the timings are not part of what was certified: the scene is done, its time unknown
    doc = json.loads(copy.read_text())
    doc["timings"]["total"] = "x"
    copy.write_text(json.dumps(doc))
    [r] = run_batch([SPEC], copy.parent)
    assert r.status == "skipped" and r.seconds is None
    with open(copy.parent / "summary.csv", newline="") as f:
        [row] = csv.DictReader(f)
    assert row["status"] == "skipped" and row["seconds"] == ""


def test_a_rerun_packs_an_edited_file_again_and_says_why(copy):
    edit(copy, _density)
    [r] = run_batch([SPEC], copy.parent)
    assert r.status == "packed" and "metrics.density reads 0.99" in r.repacked
    assert check_done(SPEC, copy)[0] is not None
    with open(copy.parent / "summary.csv", newline="") as f:
        [row] = csv.DictReader(f)
    assert "packed again" in row["message"] and "metrics.density" in row["message"]


def test_each_scenes_warnings_are_printed_and_in_the_summary(packed, tmp_path):
    # this scene ends with its mix off the tolerance: pack warns, so does batch
    shutil.copy(packed, tmp_path / "x-s2.json")
    path = tmp_path / "b.toml"
    path.write_text(f'[[scene]]\nname = "x"\ncontainer = "box:24x24x24"\n'
                    f'types = ["{P1}", "{P3}"]\nseed = 2\nfidelity = "low"\n')
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        assert main(["batch", str(path), "-o", str(tmp_path), "-q"]) == 0
    assert "warning:" in err.getvalue() and "type mix is off" in err.getvalue()
    with open(tmp_path / "summary.csv", newline="") as f:
        [row] = csv.DictReader(f)
    assert row["status"] == "skipped" and "type mix is off" in row["message"]


class _Future:
    """A Dask future's face as `run_batch` uses it, finished when `ready()` says so."""

    def __init__(self, value, ready=lambda: True):
        self.value, self.ready = value, ready

    def done(self):
        return self.ready()

    def result(self):
        if isinstance(self.value, Exception):
            raise self.value
        return self.value

    def release(self):
        pass


class _Client:
    """A cluster whose scenes' results are given up front (`results` by scene id)."""

    def __init__(self, results):
        self.results, self.cancelled = results, []

    def submit(self, fn, spec, key=None, pure=None):
        return self.results[spec.id]

    def cancel(self, futures):
        self.cancelled += futures


def test_ctrl_c_on_a_cluster_keeps_the_scenes_that_finished_meanwhile(packed, tmp_path):
    # scene "b" finishes on its worker while "a" is written, and Ctrl-C comes then
    packing = load_packing(packed)
    state = {"a written": False}
    a, b, c = (dataclasses.replace(SPEC, id=i) for i in "abc")
    client = _Client({"a": _Future(packing), "c": _Future(packing, lambda: False),
                      "b": _Future(packing, lambda: state["a written"])})

    def progress(done, total, message):
        state["a written"] = state["a written"] or message.startswith("a:")

    results = run_batch([a, b, c], tmp_path, client, progress, lambda: state["a written"])
    assert [r.status for r in results] == ["packed", "packed", "cancelled"]
    assert scene_file(tmp_path, b).is_file() and not scene_file(tmp_path, c).exists()
    assert client.cancelled == [client.results["c"]]


def test_a_scene_whose_worker_failed_fails_alone(packed, tmp_path):
    packing = load_packing(packed)
    a, b = (dataclasses.replace(SPEC, id=i) for i in "ab")
    killed = type("KilledWorker", (Exception,), {})(
        "Attempted to run task 'scene-a' on 3 different workers, but all those workers "
        "died while running it.")
    results = run_batch([a, b], tmp_path, _Client({"a": _Future(killed),
                                                   "b": _Future(packing)}))
    assert [r.status for r in results] == ["failed", "packed"]
    assert results[0].message.startswith("its worker failed: KilledWorker: Attempted")
    with open(tmp_path / "summary.csv", newline="") as f:
        assert [row["status"] for row in csv.DictReader(f)] == ["failed", "packed"]


def test_a_scene_that_fails_on_a_rerun_says_its_earlier_file_is_not_its_packing(
        copy, tmp_path, monkeypatch):
    edit(copy, _density)  # an earlier run's file that does not verify
    before = copy.read_bytes()

    def fails(spec, should_cancel=None):
        raise batch.InputError("object type a cannot fit: ...")

    monkeypatch.setattr(batch, "pack_scene", fails)
    [r] = run_batch([SPEC], tmp_path)
    assert r.status == "failed"
    assert r.message.startswith("object type a cannot fit: ... x-s2.json is an earlier "
                                "run's file, not this scene's packing (")
    assert r.message.endswith("); left as it was.") and "density" in r.message
    assert copy.read_bytes() == before
    with open(tmp_path / "summary.csv", newline="") as f:
        assert "earlier run's file" in next(csv.DictReader(f))["message"]


def test_a_failed_scenes_earlier_exports_are_named_with_its_earlier_packing(
        packed, tmp_path, monkeypatch):
    # the earlier packing was said to be left as it was; its exports beside it were not
    # named, and a print shop could print them
    spec = dataclasses.replace(SPEC, export=("stl",))
    shutil.copy(packed, scene_file(tmp_path, spec))
    run_batch([spec], tmp_path)
    edit(scene_file(tmp_path, spec), _density)

    def fails(spec, should_cancel=None):
        raise batch.InputError("object type a cannot fit: ...")

    monkeypatch.setattr(batch, "pack_scene", fails)
    [r] = run_batch([spec], tmp_path)
    assert r.status == "failed" and r.message.endswith(
        "left as it was. So are its exports beside it (x-s2.stl): print none of them for "
        "this scene."), r.message


def test_ctrl_c_writes_the_scenes_best_packing_and_a_rerun_packs_it_again(packed, tmp_path,
                                                                          monkeypatch):
    # Ctrl-C while a scene packs here: pack() returns its best certified packing so far
    stopped = load_packing(packed)
    stopped.report.stopped = "cancelled"
    empty = dataclasses.replace(SPEC, id="empty")
    nothing = load_packing(packed)
    nothing.report.stopped = "cancelled"
    nothing.type_index, nothing.rotations = nothing.type_index[:0], nothing.rotations[:0]
    nothing.translations, nothing.scales = nothing.translations[:0], nothing.scales[:0]
    monkeypatch.setattr(batch, "pack_scene",
                        lambda spec, cancel: nothing if spec.id == "empty" else stopped)
    results = run_batch([SPEC, empty], tmp_path)
    assert [r.status for r in results] == ["cancelled", "cancelled"]
    assert results[0].message == batch.CANCELLED_NOTE
    assert "not written" in results[1].message and not scene_file(tmp_path, empty).exists()
    assert check_done(SPEC, scene_file(tmp_path, SPEC)) == (
        None, "stopped by Ctrl-C before the end")
    monkeypatch.undo()
    [again] = run_batch([SPEC], tmp_path)
    assert again.status == "packed" and again.repacked == "stopped by Ctrl-C before the end"
    assert check_done(SPEC, scene_file(tmp_path, SPEC))[0] is not None


def test_ctrl_c_during_an_export_keeps_the_packing_and_the_next_run_exports(packed, tmp_path,
                                                                          monkeypatch):
    spec = dataclasses.replace(SPEC, export=("stl",))
    state = {"packed": False}

    def pack_scene(spec, cancel):
        state["packed"] = True  # Ctrl-C comes as the packing is done
        return load_packing(packed)

    monkeypatch.setattr(batch, "pack_scene", pack_scene)
    [r] = run_batch([spec], tmp_path, should_cancel=lambda: state["packed"])
    assert r.status == "cancelled" and r.message == batch.EXPORT_CANCELLED_NOTE
    assert not (tmp_path / "x-s2.stl").exists()
    [again] = run_batch([spec], tmp_path)
    assert again.status == "skipped" and again.reexported == ["x-s2.stl: missing"]
    assert (tmp_path / "x-s2.stl").is_file()


class _RunningClient(_Client):
    """A cluster that runs each submitted task here, at once: a task that raises fails the
    test (a worker would log it with its traceback)."""

    def __init__(self):
        super().__init__({})

    def submit(self, fn, spec, key=None, pure=None):
        return _Future(fn(spec))


def test_a_scene_the_engine_refuses_on_a_worker_is_a_failure_without_a_traceback(tmp_path):
    # Dask's worker logged "Compute Failed" with the PackingError's traceback, even with
    # -q, for a scene whose object cannot fit
    big = dataclasses.replace(SPEC, id="big", container="box:5x5x5", types=(P1,))
    assert isinstance(batch.pack_scene_on_worker(big), batch.SceneFailure)
    [r] = run_batch([big], tmp_path, _RunningClient())
    assert r.status == "failed" and "fit" in r.message and r.message == \
        batch.pack_scene_on_worker(big).message
    with open(tmp_path / "summary.csv", newline="") as f:
        assert [row["status"] for row in csv.DictReader(f)] == ["failed"]


def test_the_summary_keeps_the_rows_of_another_batch_run_into_the_folder(packed, tmp_path):
    # a second batch file run into the same folder replaced summary.csv, and the first
    # batch's scenes dropped out of it (their packings still there)
    shutil.copy(packed, scene_file(tmp_path, SPEC))
    run_batch([SPEC], tmp_path)
    other = dataclasses.replace(SPEC, id="big", container="box:5x5x5", types=(P1,))
    run_batch([other], tmp_path)
    with open(tmp_path / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["id"], r["status"]) for r in rows] == [("x-s2", "skipped"), ("big", "failed")]
    # the file column names the packing beside the summary, wherever the batch ran from
    assert rows[0]["file"] == "x-s2.json"
    run_batch([other, SPEC], tmp_path)  # a rerun rewrites its own rows, in its order
    with open(tmp_path / "summary.csv", newline="") as f:
        assert [r["id"] for r in csv.DictReader(f)] == ["big", "x-s2"]


def test_exports_of_a_replaced_packing_are_removed(packed, tmp_path):
    # a scene packed again (here: another seed) and now exported to 3mf only left its
    # earlier STL, of a packing that no longer exists, beside the new one
    spec = dataclasses.replace(SPEC, export=("stl", "3mf"))
    shutil.copy(packed, scene_file(tmp_path, spec))
    [first] = run_batch([spec], tmp_path)
    assert first.status == "skipped" and (tmp_path / "x-s2.stl").is_file()
    earlier = (tmp_path / "x-s2.3mf").read_bytes()
    [again] = run_batch([dataclasses.replace(spec, export=("3mf",), seed=3)], tmp_path)
    assert again.status == "packed" and again.repacked
    assert not (tmp_path / "x-s2.stl").exists()
    assert (tmp_path / "x-s2.3mf").read_bytes() != earlier
    assert again.removed == ["removed x-s2.stl: an export of an earlier packing or "
                             "settings, not made again"]
    # no exports asked any more: those of the earlier packing go, and their record
    [last] = run_batch([dataclasses.replace(spec, export=(), seed=4)], tmp_path)
    assert last.status == "packed" and not (tmp_path / "x-s2.3mf").exists()
    assert not (tmp_path / "x-s2.exports.json").exists()
    assert last.removed == ["removed x-s2.3mf: an export of an earlier packing or "
                            "settings, not made again"]


def test_an_export_edited_since_is_left_and_said_so(packed, tmp_path):
    spec = dataclasses.replace(SPEC, export=("stl",))
    shutil.copy(packed, scene_file(tmp_path, spec))
    run_batch([spec], tmp_path)
    (tmp_path / "x-s2.stl").write_bytes(b"solid mine\nendsolid mine\n")
    [again] = run_batch([dataclasses.replace(spec, export=(), seed=3)], tmp_path)
    assert again.status == "packed" and (tmp_path / "x-s2.stl").is_file()
    assert again.removed == ["left x-s2.stl: made from an earlier packing or settings, but "
                             "changed since"]
    assert (tmp_path / "x-s2.exports.json").is_file()  # still its record


def test_an_export_whose_record_was_deleted_is_made_again_saying_so(packed, tmp_path):
    # it said "exported by an older jampacked" of a record deleted by hand
    spec = dataclasses.replace(SPEC, export=("stl",))
    shutil.copy(packed, scene_file(tmp_path, spec))
    run_batch([spec], tmp_path)
    (tmp_path / "x-s2.exports.json").unlink()
    [again] = run_batch([spec], tmp_path)
    assert again.status == "skipped" and again.reexported == [
        "x-s2.stl: no record of how it was made (x-s2.exports.json is missing or unreadable, "
        "or an older jampacked exported it)"], again.reexported


def test_a_format_taken_out_of_a_scenes_exports_is_removed_and_unlisted(packed, tmp_path):
    # the file stayed, and its record went on listing it, after the batch file dropped its
    # format (and after the file was deleted by hand)
    spec = dataclasses.replace(SPEC, export=("stl", "ply"))
    shutil.copy(packed, scene_file(tmp_path, spec))
    run_batch([spec], tmp_path)
    record = tmp_path / "x-s2.exports.json"
    assert set(json.loads(record.read_text())["files"]) == {"x-s2.stl", "x-s2.ply"}
    [again] = run_batch([dataclasses.replace(spec, export=("stl",))], tmp_path)
    assert again.status == "skipped" and again.removed == [
        "removed x-s2.ply: its format is no longer asked for"], again.removed
    assert not (tmp_path / "x-s2.ply").exists() and (tmp_path / "x-s2.stl").is_file()
    assert set(json.loads(record.read_text())["files"]) == {"x-s2.stl"}
    (tmp_path / "x-s2.stl").unlink()
    [none] = run_batch([dataclasses.replace(spec, export=())], tmp_path)
    assert none.removed == [] and not record.exists()


def test_a_scene_taken_out_of_its_batch_file_leaves_the_summary(packed, tmp_path):
    # the rows of a batch file's earlier run stayed after the file dropped the scene, and
    # looked like scenes of the current batch
    shutil.copy(packed, scene_file(tmp_path, SPEC))
    other = dataclasses.replace(SPEC, id="big", container="box:5x5x5", types=(P1,))
    run_batch([SPEC], tmp_path, batch="a.toml")
    run_batch([other, dataclasses.replace(SPEC, id="gone")], tmp_path, batch="b.toml")
    run_batch([other], tmp_path, batch="b.toml")  # "gone" taken out of b.toml
    with open(tmp_path / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(r["id"], r["batch"]) for r in rows] == [("x-s2", "a.toml"), ("big", "b.toml")]


@pytest.mark.parametrize("delimiter, encoding", [(";", "utf-8-sig"), ("\t", "utf-8-sig"),
                                                 (";", "cp1252")])
def test_a_summary_a_spreadsheet_saved_with_semicolons_keeps_its_rows(packed, tmp_path,
                                                                       delimiter, encoding):
    # Excel saves a CSV with semicolons where the decimal mark is a comma; the other
    # batch's rows were read as one unknown column and lost
    shutil.copy(packed, scene_file(tmp_path, SPEC))
    run_batch([SPEC], tmp_path, batch="a.toml")
    path = tmp_path / "summary.csv"
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    rows[0]["density"] = rows[0]["density"].replace(".", ",")
    rows[0]["message"] = "vérifié"  # Excel on Windows saves its code page, not UTF-8
    with open(path, "w", newline="", encoding=encoding) as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]), delimiter=delimiter)
        w.writeheader()
        w.writerows(rows)
    other = dataclasses.replace(SPEC, id="big", container="box:5x5x5", types=(P1,))
    run_batch([other], tmp_path, batch="b.toml")
    with open(path, newline="") as f:
        again = list(csv.DictReader(f))
    assert [(r["id"], r["batch"]) for r in again] == [("x-s2", "a.toml"), ("big", "b.toml")]
    assert again[0]["density"] == rows[0]["density"] and again[0]["message"] == "vérifié"


def test_a_scene_the_file_system_refuses_says_what_stays(tmp_path, monkeypatch):
    """A full disk under a scene's packing: the scene fails with the file, the cause, and
    that finished scenes stay written (the batch caught an OSError, which save_packing now
    turns into an OutputError: its own words were lost)."""
    import re

    import jampacked.core.packing_json as packing_json

    def full(*_args, **_kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(packing_json, "_atomic_write_text", full)
    [r] = run_batch([SPEC], tmp_path)
    assert r.status == "failed"
    assert re.search(r"cannot write the packing '.*x-s2\.json' \(No space left on device\)"
                     r".*Finished scenes stay written", r.message), r.message
    assert not scene_file(tmp_path, SPEC).exists()
