"""Packing result type, its JSON file and the rotation helpers."""

from __future__ import annotations

import json
import os
import re
import shutil

import numpy as np
import pytest

from jampacked.core import packing_json as pk
from jampacked.core.errors import InputError, OutputError
from jampacked.core.meshes import file_sha256
from jampacked.core.packing import Packing, TypeRecord
from jampacked.core.packing_json import load_packing, save_packing, to_jsonable, verify_sources
from jampacked.core.rotations import matrix_to_quat, placement_matrices, quat_to_matrix


def random_quats(rng: np.random.Generator, n: int) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def translation(t) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


@pytest.fixture
def scene(tmp_path):
    """Mesh files under tmp/meshes, output folder tmp/out, and a packing of 5 objects."""
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (tmp_path / "out").mkdir()
    files = {}
    for name in ("container.stl", "apple.obj", "lemon.obj"):
        f = meshes / name
        f.write_bytes(f"solid {name}\n".encode())
        files[name] = str(f)
    rng = np.random.default_rng(7)
    n = 5
    local_a = translation([-1.0, -2.0, -3.0])
    local_b = np.diag([2.0, 2.0, 2.0, 1.0]) @ translation([0.5, 0.25, -0.125])
    packing = Packing(
        container_path=files["container.stl"],
        container_sha256=file_sha256(files["container.stl"]),
        frame_from_file=np.diag([10.0, 10.0, 10.0, 1.0]),
        container_volume=1234.5678901234567,
        types=[
            TypeRecord("apple", files["apple.obj"], file_sha256(files["apple.obj"]), 0.6,
                       local_a, 1.0 / 3.0),
            TypeRecord("lemon", files["lemon.obj"], file_sha256(files["lemon.obj"]), 0.4,
                       local_b, 0.1 + 0.2),
        ],
        type_index=np.array([0, 1, 1, 0, 1]),
        rotations=random_quats(rng, n),
        translations=rng.normal(size=(n, 3)) * 17.3,
        scales=np.ones(n),
        seed=42,
        metrics={"density": np.float64(0.61234567890123456), "nni_per_type": [1.1, None],
                 "grid": np.int64(12), "stiffness": np.float32(0.5),
                 "shares": np.array([0.6, 0.4]), "name": "default",
                 "flags": (True, np.bool_(False)), "bad": float("nan"),
                 "text": "[ 1, 2 ]\n[\n3 ]"},
        timings={"phase1": 1.25},
        certificate={"worst_overlap": np.float64(3e-7), "pairs": np.array([[0, 1], [2, 3]])},
    )
    return tmp_path, files, packing


# --------------------------------------------------------------------------- rotations


def test_quat_matrix_round_trip_random():
    rng = np.random.default_rng(0)
    q = random_quats(rng, 2000)
    r = quat_to_matrix(q)
    np.testing.assert_allclose(r @ r.transpose(0, 2, 1), np.broadcast_to(np.eye(3), r.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    q2 = matrix_to_quat(r)
    assert np.all(q2[:, 0] >= 0)
    np.testing.assert_allclose(np.linalg.norm(q2, axis=1), 1.0, atol=1e-14)
    np.testing.assert_allclose(q2, q * np.sign(q[:, :1]), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(q2), r, atol=1e-12)


def test_quat_matrix_edge_cases():
    s = np.sqrt(0.5)
    q = np.array([
        [1, 0, 0, 0],  # identity
        [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1],  # 180 degrees about x, y, z
        [0, s, s, 0], [0, 0, s, -s],  # 180 degrees about diagonals
        [s, 0, 0, s],  # 90 degrees about z
        [1e-9, 1, 0, 0],  # almost 180 degrees
    ], dtype=float)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    r = quat_to_matrix(q)
    np.testing.assert_allclose(r[6], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)
    q2 = matrix_to_quat(r)
    np.testing.assert_allclose(quat_to_matrix(q2), r, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(q2 * q, axis=1)), 1.0, atol=1e-12)


def test_placement_matrices():
    q = np.array([[np.sqrt(0.5), 0, 0, np.sqrt(0.5)]])
    m = placement_matrices(q, np.array([[1.0, 2.0, 3.0]]), np.array([2.0]))
    expected = np.array([[0, -2, 0, 1], [2, 0, 0, 2], [0, 0, 2, 3], [0, 0, 0, 1]], float)
    np.testing.assert_allclose(m[0], expected, atol=1e-15)
    assert placement_matrices(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0)).shape == (0, 4, 4)


# --------------------------------------------------------------------------- conventions


def test_vertex_convention_tiny_example(tmp_path):
    # A type whose volume centroid sits at (1, 2, 3) in its file; the vertex one unit along x
    # from it, placed with 90 degrees about z at (10, 0, 5), lands one unit along +y from there.
    local = translation([-1.0, -2.0, -3.0])
    p = Packing(
        container_path="box:20x20x20", container_sha256=None,
        frame_from_file=translation([10.0, 10.0, 10.0]), container_volume=8000.0,
        types=[TypeRecord("t", None, None, 1.0, local, 1.0)],
        type_index=np.array([0]),
        rotations=np.array([[np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)]]),
        translations=np.array([[10.0, 0.0, 5.0]]), scales=np.ones(1),
    )
    v_file = np.array([2.0, 2.0, 3.0, 1.0])
    for q in (p, _round_trip(p, tmp_path / "p.json")):
        m = q.matrices()[0]
        np.testing.assert_allclose(m @ q.types[0].local_from_file @ v_file, [10, 1, 5, 1],
                                   atol=1e-12)
        # container vertex at its file origin -> container frame (10, 10, 10)
        np.testing.assert_allclose(q.frame_from_file @ [0, 0, 0, 1], [10, 10, 10, 1])
    doc = json.loads((tmp_path / "p.json").read_text())
    m = np.array(doc["placements"][0]["matrix"])
    lf = np.array(doc["types"][0]["local_from_file"])
    np.testing.assert_allclose(m @ lf @ v_file, [10, 1, 5, 1], atol=1e-12)
    assert doc["container"]["path"] == "box:20x20x20"
    assert doc["types"][0]["path"] is None


def _round_trip(p: Packing, path) -> Packing:
    save_packing(p, path)
    return load_packing(path)


# --------------------------------------------------------------------------- save / load


def test_round_trip_preserves_everything(scene):
    tmp, files, p = scene
    out = tmp / "out" / "packing.json"
    save_packing(p, out)
    doc = json.loads(out.read_text())

    assert doc["format"] == "jampacked.packing" and doc["version"] == 2
    assert set(doc) >= {"format", "version", "container", "types", "placements", "inputs",
                        "report",
                        "seed", "metrics", "timings", "certificate"}
    assert set(doc["container"]) >= {"path", "sha256", "frame_from_file", "volume"}
    assert set(doc["types"][0]) >= {"name", "path", "sha256", "share", "local_from_file",
                                    "volume"}
    assert set(doc["placements"][0]) >= {"type", "matrix", "rotation", "translation", "scale"}
    # relative POSIX paths in the file
    assert doc["container"]["path"] == "../meshes/container.stl"
    assert [t["path"] for t in doc["types"]] == ["../meshes/apple.obj", "../meshes/lemon.obj"]
    # numpy values became plain JSON
    assert doc["metrics"]["grid"] == 12 and doc["metrics"]["shares"] == [0.6, 0.4]
    assert doc["metrics"]["flags"] == [True, False] and doc["metrics"]["bad"] is None
    assert doc["certificate"]["pairs"] == [[0, 1], [2, 3]]
    assert doc["metrics"]["text"] == "[ 1, 2 ]\n[\n3 ]"
    assert re.search(r'"rotation": \[-?\d', out.read_text())  # number lists on one line
    np.testing.assert_allclose(np.array([pl["matrix"] for pl in doc["placements"]]),
                               p.matrices(), rtol=0, atol=1e-12)

    q = load_packing(out)
    # absolute paths on load
    assert q.container_path == files["container.stl"]
    assert [t.path for t in q.types] == [files["apple.obj"], files["lemon.obj"]]
    assert all(os.path.isabs(t.path) for t in q.types)
    assert q.container_sha256 == p.container_sha256
    assert q.container_volume == p.container_volume  # full float precision
    np.testing.assert_array_equal(q.frame_from_file, p.frame_from_file)
    for a, b in zip(q.types, p.types, strict=True):
        assert (a.name, a.sha256, a.share, a.volume) == (b.name, b.sha256, b.share, b.volume)
        np.testing.assert_array_equal(a.local_from_file, b.local_from_file)
    assert q.n == p.n == 5
    assert q.type_index.dtype == np.int64
    np.testing.assert_array_equal(q.type_index, p.type_index)
    np.testing.assert_array_equal(q.rotations, p.rotations)
    np.testing.assert_array_equal(q.translations, p.translations)
    np.testing.assert_array_equal(q.scales, p.scales)
    np.testing.assert_allclose(q.matrices(), p.matrices(), rtol=0, atol=1e-12)
    assert q.seed == 42
    assert q.inputs == p.inputs and q.report == p.report
    assert q.metrics == to_jsonable(p.metrics)
    assert q.metrics["density"] == 0.61234567890123456
    assert q.timings == {"phase1": 1.25}
    assert q.certificate == {"worst_overlap": 3e-7, "pairs": [[0, 1], [2, 3]]}
    assert verify_sources(q) == []

    # saving what was loaded writes the same file
    out2 = tmp / "out" / "again.json"
    save_packing(q, out2)
    assert out2.read_text() == out.read_text()


def test_a_packing_written_through_a_symlinked_folder_opens_from_either(scene):
    # written through a symlinked folder, the paths are relative to the link's spelling
    # ("../meshes/..." from tmp/link): opened from its real folder tmp/out/sub they led to
    # tmp/out/meshes, which does not exist (now found from the real folder too, and the
    # meshes' absolute paths are recorded as spelled)
    tmp, files, p = scene
    (tmp / "out" / "sub").mkdir()
    (tmp / "link").symlink_to(tmp / "out" / "sub")
    save_packing(p, tmp / "link" / "p.json")
    doc = json.loads((tmp / "out" / "sub" / "p.json").read_text())
    assert doc["container"]["path"] == "../meshes/container.stl"
    for where in (tmp / "out" / "sub" / "p.json", tmp / "link" / "p.json"):
        q = load_packing(where)
        assert q.container_path == files["container.stl"]
        assert [t.path for t in q.types] == [files["apple.obj"], files["lemon.obj"]]
        assert verify_sources(q) == []
    # a project whose results folder is a link: a copy of the project (its own meshes, its
    # results linked elsewhere) finds its own meshes, not the original project's
    import shutil

    (tmp / "scratch").mkdir()
    (tmp / "results").symlink_to(tmp / "scratch")
    save_packing(p, tmp / "results" / "r.json")
    copy = tmp / "copy"
    shutil.copytree(tmp / "meshes", copy / "meshes")
    (tmp / "scratch2").mkdir()
    shutil.copy(tmp / "scratch" / "r.json", tmp / "scratch2" / "r.json")
    (copy / "results").symlink_to(tmp / "scratch2")
    q = load_packing(copy / "results" / "r.json")
    assert q.container_path == str(copy / "meshes" / "container.stl")
    assert [t.path for t in q.types] == [str(copy / "meshes" / n)
                                         for n in ("apple.obj", "lemon.obj")]


def test_a_mesh_that_is_a_symlink_is_recorded_as_the_link(scene):
    tmp, files, p = scene
    link = tmp / "meshes" / "latest.stl"
    link.symlink_to(files["container.stl"])
    p.container_path = str(link)
    save_packing(p, tmp / "l.json")
    doc = json.loads((tmp / "l.json").read_text())
    assert doc["container"]["path"] == "meshes/latest.stl"
    assert doc["container"]["absolute_path"] == str(link)
    assert load_packing(tmp / "l.json").container_path == str(link)


def test_a_packing_moved_alone_finds_the_meshes_where_they_stayed(scene):
    # only relative paths were written: the moved file looked for tmp/elsewhere/meshes/...
    tmp, files, p = scene
    save_packing(p, tmp / "out" / "p.json")
    doc = json.loads((tmp / "out" / "p.json").read_text())
    assert doc["container"]["absolute_path"] == files["container.stl"]
    assert [t["absolute_path"] for t in doc["types"]] == [files["apple.obj"], files["lemon.obj"]]
    (tmp / "elsewhere" / "deeper").mkdir(parents=True)
    moved = tmp / "elsewhere" / "deeper" / "p.json"
    os.replace(tmp / "out" / "p.json", moved)
    q = load_packing(moved)
    assert q.container_path == files["container.stl"]
    assert [t.path for t in q.types] == [files["apple.obj"], files["lemon.obj"]]
    assert verify_sources(q) == []


def test_a_project_moved_with_its_meshes_finds_its_own_copies(scene):
    # the relative path comes first: a copy of the project uses the copied meshes, not the
    # originals it was copied from (which still exist here)
    tmp, _, p = scene
    save_packing(p, tmp / "out" / "p.json")
    shutil.copytree(tmp / "meshes", tmp / "copy" / "meshes")
    shutil.copytree(tmp / "out", tmp / "copy" / "out")
    q = load_packing(tmp / "copy" / "out" / "p.json")
    copies = tmp / "copy" / "meshes"
    assert q.container_path == str(copies / "container.stl")
    assert [t.path for t in q.types] == [str(copies / "apple.obj"), str(copies / "lemon.obj")]
    assert verify_sources(q) == []


def test_a_file_without_absolute_paths_still_loads(saved):
    out, doc = saved
    del doc["container"]["absolute_path"]
    for t in doc["types"]:
        del t["absolute_path"]
    _write(out, doc)
    q = load_packing(out)
    assert verify_sources(q) == []


def test_a_mesh_at_neither_path_is_named_with_the_way_to_point_to_it(scene):
    tmp, files, p = scene
    save_packing(p, tmp / "out" / "p.json")
    (tmp / "elsewhere" / "deeper").mkdir(parents=True)
    os.replace(tmp / "out" / "p.json", tmp / "elsewhere" / "deeper" / "p.json")
    os.remove(files["apple.obj"])
    q = load_packing(tmp / "elsewhere" / "deeper" / "p.json")
    # the path named is the one "path" gives, which the message says to edit
    assert q.types[0].path == str(tmp / "elsewhere" / "meshes" / "apple.obj")
    problems = verify_sources(q)
    assert len(problems) == 1
    assert re.search(r"type 'apple': mesh file .*apple\.obj is missing; .*edit its \"path\" in "
                     r"the packing file to point to where the file is now", problems[0])
    # several missing: each named, the fix said once (it was repeated after each)
    for name in files:
        if os.path.exists(files[name]):
            os.remove(files[name])
    problems = verify_sources(load_packing(tmp / "elsewhere" / "deeper" / "p.json"))
    missing = [x for x in problems if " is missing" in x]
    assert len(missing) >= 2 and all(x.endswith(" is missing") for x in missing[:-1])
    assert missing[-1].count("restore them, or edit each one's \"path\"") == 1, problems


def test_empty_packing_round_trip(tmp_path):
    p = Packing("box:1x2x3", None, np.eye(4), 6.0, [TypeRecord("a", None, None, 1.0,
                np.eye(4), 0.5)], np.zeros(0, int), np.zeros((0, 4)), np.zeros((0, 3)),
                np.zeros(0))
    q = _round_trip(p, tmp_path / "e.json")
    assert q.n == 0 and q.rotations.shape == (0, 4) and q.translations.shape == (0, 3)
    assert q.container_path == "box:1x2x3"


def test_atomic_write_leaves_no_temp_files(scene, monkeypatch):
    tmp, _, p = scene
    out_dir = tmp / "out"
    out = out_dir / "p.json"
    save_packing(p, out)
    save_packing(p, out)  # overwrite an existing packing
    assert sorted(os.listdir(out_dir)) == ["p.json"]
    before = out.read_bytes()

    # a value that cannot be written: nothing changes, nothing left behind
    p.metrics["oops"] = object()
    with pytest.raises(InputError, match="metrics.oops"):
        save_packing(p, out)
    del p.metrics["oops"]
    assert out.read_bytes() == before

    # a failure at the last step: the old file stays whole and the temp file is removed
    def broken_replace(src, dst):
        raise OSError("disk full")

    p.seed = 43
    monkeypatch.setattr(pk.os, "replace", broken_replace)
    with pytest.raises(OutputError, match=r"p\.json' \(disk full\): nothing was written"):
        save_packing(p, out)
    assert sorted(os.listdir(out_dir)) == ["p.json"]
    assert out.read_bytes() == before


def test_save_into_missing_folder(scene):
    tmp, _, p = scene
    with pytest.raises(InputError, match="does not exist"):
        save_packing(p, tmp / "nope" / "p.json")


@pytest.mark.parametrize("target", ["container.stl", "apple.obj", "lemon.obj"])
def test_refuses_to_overwrite_inputs(scene, target):
    tmp, files, p = scene
    before = open(files[target], "rb").read()
    with pytest.raises(InputError, match="refusing"):
        save_packing(p, files[target])
    # also through another spelling of the same path and through a symlink
    with pytest.raises(InputError, match="refusing"):
        save_packing(p, tmp / "out" / ".." / "meshes" / target)
    link = tmp / "out" / "link.json"
    link.symlink_to(files[target])
    with pytest.raises(InputError, match="refusing"):
        save_packing(p, link)
    assert open(files[target], "rb").read() == before
    assert sorted(os.listdir(tmp / "out")) == ["link.json"]


# --------------------------------------------------------------------------- bad files


@pytest.fixture
def saved(scene):
    tmp, _, p = scene
    out = tmp / "out" / "p.json"
    save_packing(p, out)
    return out, json.loads(out.read_text())


def _write(path, doc) -> None:
    path.write_text(json.dumps(doc))


def _bad(path, doc, match: str) -> None:
    _write(path, doc)
    with pytest.raises(InputError, match=match) as err:
        load_packing(path)
    assert str(path) in str(err.value)


def test_wrong_format(saved):
    out, doc = saved
    _bad(out, dict(doc, format="something.else"), "not a jampacked packing")
    _bad(out, [1, 2, 3], "not a jampacked packing")


def test_newer_version(saved):
    out, doc = saved
    _bad(out, dict(doc, version=3), "newer jampacked")
    _bad(out, dict(doc, version="1"), "version must be an integer")


@pytest.mark.parametrize(
    "remove",
    [("version",), ("container",), ("types",), ("placements",), ("seed",), ("inputs",), ("report",),
     ("metrics",), ("timings",), ("certificate",), ("container", "frame_from_file"),
     ("container", "path"), ("types", 0, "volume"), ("types", 1, "local_from_file"),
     ("placements", 2, "rotation"), ("placements", 0, "type"), ("placements", 4, "matrix")],
)
def test_missing_field(saved, remove):
    out, doc = saved
    obj = doc
    for key in remove[:-1]:
        obj = obj[key]
    del obj[remove[-1]]
    _bad(out, doc, f"missing field .*{remove[-1]}")


def test_bad_matrix_shape(saved):
    out, doc = saved
    good = json.loads(json.dumps(doc))
    doc["container"]["frame_from_file"] = np.eye(3).tolist()
    _bad(out, doc, r"container\.frame_from_file must be a 4x4")
    doc = json.loads(json.dumps(good))
    doc["types"][1]["local_from_file"][2] = [1.0, 2.0, 3.0]
    _bad(out, doc, r"types\[1\]\.local_from_file must be a 4x4")
    doc = json.loads(json.dumps(good))
    doc["placements"][3]["matrix"] = [[1.0] * 4] * 4 + [[0.0] * 4]
    _bad(out, doc, r"placements\[3\]\.matrix must be a 4x4")
    doc = json.loads(json.dumps(good))
    doc["placements"][0]["rotation"] = [1.0, 0.0, 0.0]
    _bad(out, doc, r"placements\[0\]\.rotation must be a list of 4")


def test_matrix_disagreeing_with_placement(saved):
    out, doc = saved
    doc["placements"][1]["matrix"][0][3] += 1.0
    _bad(out, doc, r"placements\[1\]\.matrix does not match")


def test_type_index_out_of_range(saved):
    out, doc = saved
    doc["placements"][2]["type"] = 2
    # what, where, and how to fix it
    _bad(out, doc, r"placements\[2\]\.type is 2 but the file lists 2 types; it was damaged "
                   "or edited by hand: restore it, or pack again.$")
    doc["placements"][2]["type"] = -1
    _bad(out, doc, "type is -1")


def test_a_file_with_a_byte_order_mark_loads(saved):
    # a packing saved by a Windows editor starts with a UTF-8 BOM: it was "not valid JSON"
    out, doc = saved
    out.write_bytes(b"\xef\xbb\xbf" + json.dumps(doc).encode())
    q = load_packing(out)
    assert q.n == 5 and verify_sources(q) == []


def test_not_json_and_missing_file(tmp_path):
    f = tmp_path / "broken.json"
    f.write_text('{"format": "jampacked.packing", "version": 1, "contai')
    with pytest.raises(InputError, match="not valid JSON") as err:
        load_packing(f)
    assert str(f) in str(err.value)
    with pytest.raises(InputError, match="cannot read packing file"):
        load_packing(tmp_path / "absent.json")


# --------------------------------------------------------------------------- sources


def test_verify_sources(scene):
    tmp, files, p = scene
    out = tmp / "out" / "p.json"
    save_packing(p, out)
    q = load_packing(out)
    assert verify_sources(q) == []
    with open(files["apple.obj"], "ab") as f:
        f.write(b"edited\n")
    os.remove(files["container.stl"])
    problems = verify_sources(q)
    assert len(problems) == 2
    assert "container" in problems[0] and "missing" in problems[0]
    assert "apple" in problems[1] and "changed" in problems[1]
    # a spec container and a type without a file are not problems
    q.container_path = "box:1x1x1"
    q.types[0].path = None
    assert verify_sources(q) == []


# --------------------------------------------------------------------------- hostile files


@pytest.mark.parametrize("where", [("container", "volume"), ("types", 0, "share"),
                                   ("placements", 1, "rotation", 2),
                                   ("placements", 0, "translation", 0)])
def test_huge_integer_in_a_number_field_is_refused_by_name(saved, where):
    out, doc = saved
    obj = doc
    for key in where[:-1]:
        obj = obj[key]
    obj[where[-1]] = 10 ** 400
    _bad(out, doc, f"{where[0]}.*must be a finite number")


def test_deeply_nested_json_is_refused(saved):
    out, _ = saved
    out.write_text('{"format": "jampacked.packing", "version": 2, "x": '
                   + "[" * 200000 + "]" * 200000 + "}")
    with pytest.raises(InputError, match="nested too deeply") as err:
        load_packing(out)
    assert str(out) in str(err.value)


def test_odd_report_fields_are_ignored_and_odd_inputs_refused(saved):
    out, doc = saved
    doc["report"].update(repair="x", attempts=5, stopped=["no"], fidelity={"a": 1},
                         spheres_per_type=[1, "two"], warnings="text")
    _write(out, doc)
    q = load_packing(out)
    assert q.report.repair.rounds == 0 and q.report.attempts == []
    assert q.report.stopped is None and q.report.warnings == []
    for key, value in (("clearance", [1.0]), ("clearance", "0.5"), ("time_budget", {}),
                       ("options", "fast"), ("clearance", 10 ** 400)):
        bad = json.loads(json.dumps(doc))
        bad["inputs"][key] = value
        _bad(out, bad, f"inputs.{key}")


def test_version_1_params_map_to_the_typed_fields(saved):
    out, doc = saved
    params = {"clearance": 0.5, "fidelity": "low", "fidelity_requested": "auto",
              "extra_max_tvd": 0.01, "extra_passes": [0.8, 0.5], "mode": 0, "k_obj": 1.0,
              "stopped": "deadline", "time_budget": 20.0, "unknown_key": [1, 2],
              "repair": {"rounds": 2, "moved": 3, "removed": 1, "first": {"certified": False},
                         "timed_out": False},
              "attempts": [{"density": 0.4, "count": 30, "seconds": 2.5, "phase1": 1.0,
                            "phase2": 0.5, "extra": 1.0, "stopped": None}],
              "phase1": {"inserted": 9, "grown": 7, "failed": 2, "seconds": 1.0,
                         "stopped": "", "extra": {}},
              "fidelity_detail": {"name": "low", "spheres": 24, "grid_cells": 28,
                                  "surface_points": 96, "container_cells": 3.0,
                                  "reasons": ["preset"]},
              "threads": {"most": 2, "switches": 0, "probes": 1,
                          "seconds_by_threads": {"1": 0.5, "2": 1.0}}}
    old = {k: v for k, v in doc.items() if k not in ("inputs", "report")}
    _write(out, dict(old, version=1, params=params))
    q = load_packing(out)
    assert q.inputs.clearance == 0.5 and q.inputs.fidelity == "auto"
    assert q.inputs.time_budget == 20.0
    assert q.inputs.options.cavity.max_tvd == 0.01
    assert q.inputs.options.cavity.factors == (0.8, 0.5)
    assert q.report.fidelity == "low" and q.report.stopped == "deadline"
    assert q.report.repair.moved == 3 and q.report.repair.first == {"certified": False}
    assert q.report.attempts[0].count == 30 and q.report.phase1.grown == 7
    assert q.report.fidelity_detail.spheres == 24
    assert q.report.fidelity_detail.reasons == ("preset",)
    assert q.report.threads.seconds_by_threads == {"1": 0.5, "2": 1.0}
    # pack() wrote the extra passes' statistics over the option of the same name
    params["extra_passes"] = [{"inserted": 5, "grown": 4, "failed": 1, "seconds": 0.2,
                               "stopped": "patience", "extra": {}, "round": 0,
                               "factor": 0.8}]
    _write(out, dict(old, version=1, params=params))
    q = load_packing(out)
    assert q.inputs.options.cavity.factors == (0.8, 0.6, 0.5, 0.4)
    assert q.report.extra_passes[0].grown == 4 and q.report.extra_passes[0].factor == 0.8


@pytest.mark.parametrize("where, value, match", [
    (("rotation", 1), True, r"placements\[1\]\.rotation must be a list of 4 numbers"),
    (("rotation",), [0, 0, 0, 0], r"placements\[1\]\.rotation must be a non-zero quaternion"),
    (("scale",), "1.0", r"placements\[1\]\.scale must be a number"),
    (("scale",), False, r"placements\[1\]\.scale must be a number"),
    (("matrix", 0, 3), "2", r"placements\[1\]\.matrix must be a 4x4"),
    (("translation",), {"x": 1}, r"placements\[1\]\.translation must be a list of 3"),
    (("type",), 1.0, r"placements\[1\]\.type must be an integer"),
])
def test_a_bad_placement_is_named_among_good_ones(saved, where, value, match):
    # the whole list is read in one pass; a bad value anywhere must still be named
    out, doc = saved
    obj = doc["placements"][1]
    for key in where[:-1]:
        obj = obj[key]
    obj[where[-1]] = value
    _bad(out, doc, match)


@pytest.mark.parametrize("scale, match", [(-0.5, "a negative scale mirrors the object"),
                                          (0.0, "0 shrinks the object")])
def test_a_scale_that_is_not_positive_is_refused_by_name(saved, scale, match):
    # a mirrored placement edited consistently (scale and matrix together) was accepted, and
    # export certified and wrote the mirror image
    out, doc = saved
    pl = doc["placements"][3]
    pl["scale"] = scale
    pl["matrix"] = placement_matrices(np.array([pl["rotation"]]), np.array([pl["translation"]]),
                                      np.array([scale]))[0].tolist()
    _bad(out, doc, rf"placements\[3\]\.scale must be > 0, got {scale:g}: {match}")
    doc["placements"][4].update(scale=-1.0, rotation=[1, 0, 0, 0], translation=[0, 0, 0],
                                matrix=np.diag([-1.0, -1, -1, 1]).tolist())
    _bad(out, doc, r"placements\[3\]\.scale must be > 0.*\(and 1 more placements\)")


@pytest.mark.parametrize("where", ["container", "type"])
def test_a_path_with_a_nul_character_is_refused_by_name(saved, where):
    # export then crashed with "ValueError: embedded null byte" from os.path.realpath
    # (the shared fuzzer, seed 4374, case 193)
    path, doc = saved
    if where == "container":
        doc["container"]["path"] = "a\x00b.stl"
        match = r"container\.path holds a NUL character"
    else:
        doc["types"][0]["path"] = "a\x00b.stl"
        match = r"types\[0\]\.path holds a NUL character"
    _bad(path, doc, match)


def test_verify_sources_names_an_unreadable_mesh(scene, monkeypatch):
    # file_sha256 names a refused read as a MeshError, which escaped verify_sources (which
    # never raises: `info` lists the problem)
    from jampacked.core import packing_json
    from jampacked.core.errors import MeshError

    tmp, files, p = scene

    def refused(path):
        raise MeshError(f"Mesh file '{path}' cannot be read (Permission denied)")

    monkeypatch.setattr(packing_json, "file_sha256", refused)
    problems = verify_sources(p)
    assert len(problems) == 3 and all("cannot read mesh file" in q for q in problems)
    assert "Permission denied" in problems[0]
