"""Tests for jampacked.core.meshes: loading, checks, repairs, volumes."""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

import manifold3d
import numpy as np
import pytest
import trimesh
from testdata import mesh_path, mesh_paths

from jampacked.core.errors import InputError, MeshError
from jampacked.core.mesh_files import read_mesh_arrays
from jampacked.core.meshes import (
    MeshData,
    box_mesh,
    file_sha256,
    load_mesh,
    mesh_volume_centroid,
    parse_box_spec,
)


def assert_closed_oriented(mesh: MeshData) -> None:
    """Independent check: each undirected edge twice, each directed edge once."""
    f = mesh.faces
    assert f.dtype == np.int64 and f.ndim == 2 and f.shape[1] == 3
    assert mesh.vertices.dtype == np.float64 and mesh.vertices.shape[1] == 3
    directed = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, dcounts = np.unique(directed, axis=0, return_counts=True)
    _, ucounts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(ucounts == 2), "every edge is used by exactly two faces"
    assert np.all(dcounts == 1), "every directed edge is used once (consistent winding)"
    assert len(np.unique(f)) == len(mesh.vertices), "no unreferenced vertices"
    assert mesh.volume > 0
    m = manifold3d.Manifold(
        manifold3d.Mesh(
            vert_properties=mesh.vertices.astype(np.float32),
            tri_verts=mesh.faces.astype(np.uint32),
        )
    )
    assert m.status() == manifold3d.Error.NoError


def write_obj(path: Path, vertices, faces) -> Path:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, float)]
    lines += ["f " + " ".join(str(int(i) + 1) for i in face) for face in faces]
    path.write_text("\n".join(lines) + "\n")
    return path


def unit_box() -> tuple[np.ndarray, np.ndarray]:
    box = box_mesh((2.0, 3.0, 4.0))
    return np.array(box.vertices), np.array(box.faces)


# ------------------------------------------------------------------------------------------
# the broken test meshes


def test_spot_with_holes_is_open():
    path = mesh_path("broken/spot_with_holes.obj")
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    msg = str(info.value)
    assert "spot_with_holes.obj" in msg
    assert "not closed" in msg and "open boundary edges" in msg and "5 holes" in msg
    assert "Fix:" in msg


def test_pear_five_bodies_slivers_removed(caplog):
    path = mesh_path("broken/pear_five_bodies.ply")
    with caplog.at_level(logging.WARNING, logger="jampacked.core.meshes"):
        mesh = load_mesh(path)
    assert_closed_oriented(mesh)
    text = " ".join(mesh.warnings)
    assert "pear_five_bodies.ply" in text
    assert "sliver" in text and "degenerate" in text
    assert all("pear_five_bodies.ply" in w for w in mesh.warnings)
    # the same warnings went through logging
    logged = [r.getMessage() for r in caplog.records]
    assert all(w in logged for w in mesh.warnings)
    # same solid as the cleaned copy of the pear
    clean = load_mesh(mesh_path("fruit/ycb/016_pear.ply"))
    assert clean.warnings == ()
    assert len(mesh.faces) == len(clean.faces)
    assert mesh.volume == pytest.approx(clean.volume, rel=1e-9)


def test_polytope_malformed_face():
    path = mesh_path("broken/polytope_malformed_face.obj")
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    msg = str(info.value)
    assert "polytope_malformed_face.obj" in msg
    assert "malformed polygon" in msg and "line 17" in msg and "vertex 12 twice" in msg


def test_polytope_internal_faces():
    # trimesh's OBJ reader fails on the comments on face lines: the tolerant reader reads it,
    # then the internal faces are found.
    path = mesh_path("broken/polytope_internal_faces.obj")
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    msg = str(info.value)
    assert "polytope_internal_faces.obj" in msg
    assert "non-manifold edges" in msg and "internal faces" in msg
    assert "cannot be read" not in msg


def test_vase_thin_wall():
    path = mesh_path("broken/vase_thin_wall_shell.stl")
    mesh = load_mesh(path, role="object")
    assert_closed_oriented(mesh)
    with pytest.raises(MeshError) as info:
        load_mesh(path, role="container")
    msg = str(info.value)
    assert "vase_thin_wall_shell.stl" in msg
    assert "thin wall" in msg and "cavity" in msg and "inside surface" in msg


# ------------------------------------------------------------------------------------------
# the good test meshes


@pytest.mark.parametrize("relative", mesh_paths("containers/*"))
def test_shared_containers(relative):
    mesh = load_mesh(mesh_path(relative), role="container")
    assert_closed_oriented(mesh)
    assert mesh.warnings == ()


@pytest.mark.parametrize(
    "relative",
    mesh_paths("fruit/ycb_lowpoly/*.obj")
    + ["fruit/ycb/015_peach.ply", "fruit/ycb/016_pear.ply"]
    + mesh_paths("polyhedra/*/*.obj"),
)
def test_shared_objects(relative, caplog):
    with caplog.at_level(logging.WARNING):
        mesh = load_mesh(mesh_path(relative))
    assert_closed_oriented(mesh)
    assert mesh.warnings == ()
    # the lowpoly OBJ files name missing .mtl files: that stays quiet
    assert [r for r in caplog.records if r.levelno >= logging.WARNING] == []


def test_blender_uv_seams_merged():
    path = mesh_path("fruit/ycb_lowpoly/011_banana.obj")
    raw = trimesh.load(path, force="mesh", process=False)
    mesh = load_mesh(path)
    assert len(mesh.vertices) < len(raw.vertices)  # split at UV seams in the file
    assert len(mesh.faces) == len(raw.faces)


def test_sha256_and_metadata():
    path = mesh_path("polyhedra/convex5/polytope1.obj")
    mesh = load_mesh(str(path))
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    assert mesh.sha256 == digest == file_sha256(path)
    assert mesh.path == str(path)
    assert not mesh.vertices.flags.writeable and not mesh.faces.flags.writeable
    assert np.allclose(mesh.extents, mesh.vertices.max(0) - mesh.vertices.min(0))


@pytest.mark.parametrize(
    "relative",
    [
        "containers/hand.obj",
        "fruit/ycb_lowpoly/014_lemon.obj",
        "polyhedra/nonconvex10/polytope3.obj",
    ],
)
def test_volume_centroid_against_trimesh(relative):
    mesh = load_mesh(mesh_path(relative))
    tm = trimesh.Trimesh(np.array(mesh.vertices), np.array(mesh.faces), process=False)
    volume, centroid = mesh_volume_centroid(mesh.vertices, mesh.faces)
    assert volume == pytest.approx(tm.volume, rel=1e-9)
    assert mesh.volume == pytest.approx(volume, rel=1e-12)
    scale = np.linalg.norm(mesh.extents)
    assert np.allclose(centroid, tm.center_mass, atol=1e-9 * scale)
    assert np.allclose(mesh.centroid, centroid)


# ------------------------------------------------------------------------------------------
# meshes broken on purpose


def test_clean_box_file(tmp_path):
    v, f = unit_box()
    mesh = load_mesh(write_obj(tmp_path / "box.obj", v, f))
    assert_closed_oriented(mesh)
    assert mesh.volume == pytest.approx(24.0)
    assert mesh.warnings == ()


def test_a_mesh_too_far_from_the_origin_for_its_size_is_refused(tmp_path):
    # the fuzzer's cube at -1e15 packed, and the packing file's matrices, applied as the
    # README says, moved it by float64's step there (0.125): 0.84% overlap with a neighbour
    v, f = unit_box()
    path = write_obj(tmp_path / "far.obj", v * 4.0 - 1e15, f)
    with pytest.raises(MeshError, match=r"far.obj' lies 1e\+15 units from the origin but "
                       r"is only 16 across: .* step by 0.125 units .*Move it near the origin"):
        load_mesh(path)
    # a georeferenced part (6,000 km out, in mm, 16 mm across) is fine
    assert load_mesh(write_obj(tmp_path / "utm.obj", v * 4.0 + 6e9, f)).volume == \
        pytest.approx(24.0 * 64, rel=1e-6)


def test_hole_is_an_error(tmp_path):
    v, f = unit_box()
    path = write_obj(tmp_path / "holed.obj", v, f[1:])
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    msg = str(info.value)
    assert "holed.obj" in msg and "not closed" in msg
    assert "3 open boundary edges" in msg and "1 hole" in msg


def test_flipped_face_is_repaired(tmp_path):
    v, f = unit_box()
    f[5] = f[5][::-1]
    mesh = load_mesh(write_obj(tmp_path / "flipped.obj", v, f))
    assert_closed_oriented(mesh)
    assert mesh.volume == pytest.approx(24.0)
    assert len(mesh.warnings) == 1
    assert "flipped.obj" in mesh.warnings[0] and "flipped 1 face" in mesh.warnings[0]


def test_inverted_mesh_is_repaired(tmp_path):
    v, f = unit_box()
    mesh = load_mesh(write_obj(tmp_path / "inverted.obj", v, f[:, ::-1]))
    assert_closed_oriented(mesh)
    assert mesh.volume == pytest.approx(24.0)
    assert len(mesh.warnings) == 1 and "inside out" in mesh.warnings[0]
    assert "inverted.obj" in mesh.warnings[0]


def test_duplicate_face_is_repaired(tmp_path):
    v, f = unit_box()
    mesh = load_mesh(write_obj(tmp_path / "dup.obj", v, np.vstack([f, f[3:4]])))
    assert_closed_oriented(mesh)
    assert len(mesh.faces) == 12
    assert len(mesh.warnings) == 1 and "duplicate face" in mesh.warnings[0]


def test_duplicate_vertices_merged_silently(tmp_path):
    v, f = unit_box()
    soup = v[f].reshape(-1, 3)  # every face has its own three vertices, like STL
    soup[::2] += 1e-13  # and some are off by far less than the merge tolerance
    faces = np.arange(len(soup)).reshape(-1, 3)
    mesh = load_mesh(write_obj(tmp_path / "soup.obj", soup, faces))
    assert_closed_oriented(mesh)
    assert len(mesh.vertices) == 8
    assert mesh.warnings == ()
    trimesh.Trimesh(soup, faces, process=False).export(tmp_path / "soup.stl")
    stl = load_mesh(tmp_path / "soup.stl")
    assert len(stl.vertices) == 8 and stl.warnings == ()


def test_degenerate_faces_are_repaired(tmp_path):
    v, f = unit_box()
    # a triangle with a repeated vertex
    with_repeat = np.vstack([f, [[0, 0, 1]]])
    mesh = load_mesh(write_obj(tmp_path / "repeat.obj", v, with_repeat))
    assert_closed_oriented(mesh)
    assert len(mesh.warnings) == 1 and "degenerate" in mesh.warnings[0]
    # a needle: a T-junction closed by a zero-area face
    a, b, c_face = f[0]
    c = len(v)
    v2 = np.vstack([v, 0.5 * (v[a] + v[b])])
    split = [[a, c, c_face], [c, b, c_face]]
    needle = [[a, b, c]]
    faces = np.vstack([split, f[1:], needle])
    mesh = load_mesh(write_obj(tmp_path / "needle.obj", v2, faces))
    assert_closed_oriented(mesh)
    assert mesh.volume == pytest.approx(24.0)
    assert len(mesh.warnings) == 1 and "1 degenerate face" in mesh.warnings[0]


def test_sliver_bodies_are_removed(tmp_path):
    v, f = unit_box()
    # a closed but flat piece (zero volume) beside the box, and a tiny stray triangle
    flat_v = np.array([[5, 0, 0], [6, 0, 0], [6, 1, 0], [5, 1, 0]], float)
    flat_f = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 3], [1, 3, 2]]) + len(v)
    speck_v = np.array([[9, 9, 9], [9 + 1e-5, 9, 9], [9, 9 + 1e-5, 9]])
    speck_f = np.array([[0, 1, 2]]) + len(v) + 4
    vertices = np.vstack([v, flat_v, speck_v])
    faces = np.vstack([f, flat_f, speck_f])
    mesh = load_mesh(write_obj(tmp_path / "specks.obj", vertices, faces))
    assert_closed_oriented(mesh)
    assert len(mesh.vertices) == 8 and mesh.volume == pytest.approx(24.0)
    assert len(mesh.warnings) == 1
    assert "specks.obj" in mesh.warnings[0] and "2 zero-volume sliver bodies" in mesh.warnings[0]


def test_two_bodies_is_an_error(tmp_path):
    v, f = unit_box()
    vertices = np.vstack([v, v + [10.0, 0, 0]])
    faces = np.vstack([f, f + len(v)])
    path = write_obj(tmp_path / "two.obj", vertices, faces)
    for role in ("object", "container"):
        with pytest.raises(MeshError) as info:
            load_mesh(path, role=role)
        assert "two.obj" in str(info.value) and "2 separate bodies" in str(info.value)
    # two rooms apart: a union alone would leave them two (the advice said to union them)
    assert "pack each part on its own" in " ".join(str(info.value).split())
    # a hollow solid: an inner surface nested inside the outer one
    nested = np.vstack([v, 0.5 * v])
    faces = np.vstack([f, f[:, ::-1] + len(v)])
    with pytest.raises(MeshError) as info:
        load_mesh(write_obj(tmp_path / "hollow.obj", nested, faces), role="container")
    assert "2 separate bodies" in str(info.value) and "inside another" in str(info.value)
    assert "delete the extra surfaces" in str(info.value)
    # as an object: a union keeps the void, so the advice is to delete the inner surface
    with pytest.raises(MeshError) as info:
        load_mesh(write_obj(tmp_path / "hollow.obj", nested, faces), role="object")
    msg = " ".join(str(info.value).split())
    assert "delete the inner surface" in msg
    # two objects apart (a pair of cherries): a union alone leaves two bodies
    with pytest.raises(MeshError) as info:
        load_mesh(path, role="object")
    msg = " ".join(str(info.value).split())
    assert "a union alone leaves them apart" in msg and "separate types" in msg


def test_non_orientable_is_an_error(tmp_path):
    # the 6-vertex real projective plane: closed, every edge used twice, no consistent winding
    faces = np.array(
        [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5], [0, 5, 1],
         [1, 2, 4], [2, 3, 5], [3, 4, 1], [4, 5, 2], [5, 1, 3]]
    )
    _, counts = np.unique(np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), 1), axis=0,
                          return_counts=True)
    assert np.all(counts == 2)
    vertices = np.random.default_rng(0).normal(size=(6, 3))
    with pytest.raises(MeshError) as info:
        load_mesh(write_obj(tmp_path / "rp2.obj", vertices, faces))
    assert "rp2.obj" in str(info.value) and "cannot be made consistent" in str(info.value)


def test_zero_volume_is_an_error(tmp_path):
    # a flat square, closed: top and bottom triangulated along different diagonals
    vertices = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    faces = [[0, 1, 2], [0, 2, 3], [1, 0, 3], [1, 3, 2]]
    with pytest.raises(MeshError) as info:
        load_mesh(write_obj(tmp_path / "flat.obj", vertices, faces))
    assert "flat.obj" in str(info.value) and "zero volume" in str(info.value)


def test_thin_walled_cup_container(tmp_path):
    outer = manifold3d.Manifold.cylinder(50.0, 20.0, 20.0, 64)
    inner = manifold3d.Manifold.cylinder(50.0, 18.0, 18.0, 64).translate((0.0, 0.0, 2.0))
    cup = (outer - inner).to_mesh()
    path = tmp_path / "cup.stl"
    trimesh.Trimesh(np.asarray(cup.vert_properties)[:, :3], np.asarray(cup.tri_verts),
                    process=False).export(path)
    assert load_mesh(path, role="object").volume > 0
    with pytest.raises(MeshError) as info:
        load_mesh(path, role="container")
    assert "cup.stl" in str(info.value) and "thin wall" in str(info.value)
    # a solid cylinder is a fine container
    solid = outer.to_mesh()
    path = tmp_path / "can.stl"
    trimesh.Trimesh(np.asarray(solid.vert_properties)[:, :3], np.asarray(solid.tri_verts),
                    process=False).export(path)
    assert_closed_oriented(load_mesh(path, role="container"))


def test_obj_comments_on_face_lines(tmp_path):
    v, f = unit_box()
    path = tmp_path / "commented.obj"
    lines = [f"v {x} {y} {z}  # corner" for x, y, z in v]
    lines += [f"f {a + 1} {b + 1} {c + 1} # face" for a, b, c in f]
    path.write_text("# header\n" + "\n".join(lines) + "\n")
    mesh = load_mesh(path)
    assert_closed_oriented(mesh)
    assert mesh.volume == pytest.approx(24.0)


# ------------------------------------------------------------------------------------------
# files that cannot be read, bad arguments


def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match=r"nothere\.stl' does not exist"):
        load_mesh(tmp_path / "nothere.stl")


def test_unknown_extension(tmp_path):
    path = tmp_path / "mesh.foo"
    path.write_text("solid\n")
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert "mesh.foo" in str(info.value) and "unknown file type" in str(info.value)


def test_empty_and_garbage_files(tmp_path):
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    with pytest.raises(MeshError, match=r"empty\.stl.*empty file"):
        load_mesh(empty)
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"this is not a ply file\n\x00\x01\x02")
    with pytest.raises(MeshError, match=r"garbage\.ply"):
        load_mesh(garbage)
    points = tmp_path / "points.obj"
    points.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError, match=r"points\.obj.*no triangles"):
        load_mesh(points)


def test_bad_role():
    with pytest.raises(InputError, match="role"):
        load_mesh("whatever.stl", role="bucket")


# ------------------------------------------------------------------------------------------
# boxes and volumes


def test_parse_box_spec():
    assert parse_box_spec("box:43.4338x41.8435x45.0059") == (43.4338, 41.8435, 45.0059)
    assert parse_box_spec("BOX: 1 x 2 x 3") == (1.0, 2.0, 3.0)
    assert parse_box_spec("containers/box.stl") is None
    assert parse_box_spec("boxes.obj") is None
    for bad in ("box:", "box:1x2", "box:1x2x3x4", "box:axbxc", "box:1x0x3", "box:1x-2x3",
                "box:1xinfx3"):
        with pytest.raises(InputError, match="box"):
            parse_box_spec(bad)


def test_box_mesh():
    box = box_mesh((43.4338, 41.8435, 45.0059))
    assert len(box.faces) == 12 and len(box.vertices) == 8
    assert box.path is None and box.sha256 is None and box.warnings == ()
    assert box.volume == pytest.approx(43.4338 * 41.8435 * 45.0059, rel=1e-12)
    volume, centroid = mesh_volume_centroid(box.vertices, box.faces)
    assert volume == pytest.approx(box.volume, rel=1e-12)
    assert np.allclose(centroid, 0.0) and np.allclose(box.centroid, 0.0)
    assert np.allclose(box.extents, (43.4338, 41.8435, 45.0059))
    assert_closed_oriented(box)
    with pytest.raises(InputError):
        box_mesh((1.0, 0.0, 1.0))


def test_volume_centroid_offset_and_inverted():
    box = box_mesh((1.0, 2.0, 3.0))
    shifted = np.asarray(box.vertices) + [1e3, -5.0, 7.0]
    volume, centroid = mesh_volume_centroid(shifted, box.faces)
    assert volume == pytest.approx(6.0, rel=1e-12)
    assert np.allclose(centroid, [1e3, -5.0, 7.0])
    volume, _ = mesh_volume_centroid(box.vertices, np.asarray(box.faces)[:, ::-1])
    assert volume == pytest.approx(-6.0, rel=1e-12)


def test_mesh_from_arrays_checks_and_repairs_like_load_mesh():
    """Meshes from memory (Blender objects) get the same checks, named by their name."""
    from jampacked.core.meshes import mesh_from_arrays

    sphere = trimesh.creation.icosphere(subdivisions=2)
    m = mesh_from_arrays(sphere.vertices, sphere.faces[:, ::-1], name="Sphere.001")
    assert m.path is None and m.sha256 is None and m.volume > 0
    assert len(m.warnings) == 1 and "Sphere.001" in m.warnings[0]
    with pytest.raises(MeshError, match="Cup.*not closed"):
        mesh_from_arrays(sphere.vertices, sphere.faces[:-2], name="Cup", role="container")
    with pytest.raises(InputError, match="face indices"):
        mesh_from_arrays(sphere.vertices, sphere.faces + 10_000, name="Bad")
    with pytest.raises(InputError, match="triangles"):
        mesh_from_arrays(sphere.vertices, np.zeros((2, 4), int), name="Quads")


# ------------------------------------------------------------------------------------------
# 3MF units


def write_3mf(path: Path, vertices, faces, unit: str | None) -> Path:
    """A one-object 3MF package written by hand, declaring `unit` (None: no attribute)."""
    import zipfile

    from jampacked.core import threemf

    declared = "" if unit is None else f' unit="{unit}"'
    model = (f'<?xml version="1.0" encoding="UTF-8"?>\n<model{declared} '
             f'xmlns="{threemf.CORE_NAMESPACE}"><resources><object id="1" type="model">'
             "<mesh><vertices>"
             + "".join(f'<vertex x="{x!r}" y="{y!r}" z="{z!r}"/>'
                       for x, y, z in np.asarray(vertices, float).tolist())
             + "</vertices><triangles>"
             + "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"/>' for a, b, c in faces)
             + '</triangles></mesh></object></resources><build><item objectid="1"/></build>'
             "</model>\n")
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("[Content_Types].xml", threemf.CONTENT_TYPES)
        archive.writestr("_rels/.rels", threemf.RELATIONSHIPS)
        archive.writestr("3D/3dmodel.model", model)
    return path


@pytest.mark.parametrize(("unit", "mm"), [(None, 1.0), ("millimeter", 1.0), ("micron", 1e-3),
                                          ("centimeter", 10.0), ("inch", 25.4),
                                          ("foot", 304.8), ("meter", 1000.0)])
def test_3mf_declared_unit_is_read_in_millimetres(tmp_path, unit, mm):
    """A 3MF model in inches is 25.4 times larger in millimetres, as slicers read it; the
    conversion is said (the README's lengths are millimetres for printing)."""
    v, f = unit_box()
    mesh = load_mesh(write_3mf(tmp_path / "box.3mf", v, f, unit), role="container")
    assert mesh.volume == pytest.approx(24.0 * mm ** 3, rel=1e-12)
    assert np.ptp(mesh.vertices, axis=0) == pytest.approx(np.array([2.0, 3.0, 4.0]) * mm)
    if mm == 1.0:
        assert mesh.warnings == ()
    else:
        assert len(mesh.warnings) == 1
        assert f"unit as {unit}" in mesh.warnings[0] and "millimetres" in mesh.warnings[0]
        assert "box.3mf" in mesh.warnings[0]


def test_3mf_unknown_unit_is_a_clear_error(tmp_path):
    v, f = unit_box()
    path = write_3mf(tmp_path / "box.3mf", v, f, "furlong")
    with pytest.raises(MeshError, match=r"unit 'furlong' is not one of 3MF's units .*inch"):
        load_mesh(path)


def test_unwelded_faces_are_told_apart_from_holes(tmp_path):
    """Faces whose corners were rounded apart (every triangle its own piece) were reported
    as hundreds of holes, with 'fill the holes' as the fix; the fix is to merge vertices."""
    import trimesh as tm

    s = tm.creation.icosphere(subdivisions=2, radius=10.0)
    corners = np.asarray(s.vertices)[np.asarray(s.faces)].reshape(-1, 3)
    corners = corners + np.random.default_rng(3).normal(scale=1e-6, size=corners.shape)
    path = write_obj(tmp_path / "cracked.obj", corners, np.arange(len(corners)).reshape(-1, 3))
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    text = " ".join(str(info.value).split())
    assert "not joined" in text and "Merge by Distance" in text and "fill the holes" not in text
    with pytest.raises(MeshError, match="fill the holes"):  # a real hole keeps its advice
        load_mesh(write_obj(tmp_path / "holed.obj", s.vertices, np.asarray(s.faces)[1:]))


def test_3mf_unit_written_as_writers_write_it(tmp_path):
    """unit="mm" or "Inches" is not the specification's spelling, but some writers use it:
    read as millimetre and inch (it was refused once units were read)."""
    v, f = unit_box()
    assert load_mesh(write_3mf(tmp_path / "a.3mf", v, f, "mm")).volume == pytest.approx(24.0)
    inch = load_mesh(write_3mf(tmp_path / "b.3mf", v, f, "Inches"))
    assert inch.volume == pytest.approx(24.0 * 25.4 ** 3)
    assert "unit as inch" in inch.warnings[0]


def test_a_binary_stl_cut_short_is_named_as_such(tmp_path):
    # a truncated STL was reported as "no triangles (empty, points or lines only)"; pack
    # and validate now say it was cut short, with both counts
    box = trimesh.creation.box((10, 20, 30))
    whole = trimesh.exchange.stl.export_stl(box)
    (tmp_path / "whole.stl").write_bytes(whole)
    assert len(load_mesh(tmp_path / "whole.stl").faces) == 12
    cut = tmp_path / "cut.stl"
    cut.write_bytes(whole[:-10])
    with pytest.raises(MeshError, match=r"cut\.stl' is not a whole STL file: its header "
                                        r"says 12 triangles \(684 bytes\), but it has 674"):
        load_mesh(cut)
    miscounted = tmp_path / "miscounted.stl"  # the header's count one too many
    miscounted.write_bytes(whole[:80] + (13).to_bytes(4, "little") + whole[84:])
    with pytest.raises(MeshError, match="header says 13 triangles"):
        read_mesh_arrays(miscounted)
    # a binary STL whose header starts with "solid" (as some CAD tools write) and an ASCII
    # STL still read
    solid = tmp_path / "solid-header.stl"
    solid.write_bytes(b"solid part".ljust(80, b" ") + whole[80:])
    assert len(read_mesh_arrays(solid)[1]) == 12
    ascii_stl = tmp_path / "ascii.stl"
    ascii_stl.write_text(trimesh.exchange.stl.export_stl_ascii(box))
    assert len(read_mesh_arrays(ascii_stl)[1]) == 12
    # ASCII with a UTF-8 byte-order mark (Windows tools) or a name line over 4 KB: read
    # as before, never taken for a binary STL of the wrong size
    text = trimesh.exchange.stl.export_stl_ascii(box)
    bom = tmp_path / "bom.stl"
    bom.write_bytes(b"\xef\xbb\xbf" + text.encode())
    long_name = tmp_path / "long-name.stl"
    long_name.write_text(text.replace("solid", "solid " + "x" * 5000, 1))
    for path in (bom, long_name):
        assert len(read_mesh_arrays(path)[1]) == 12, path
    padded = tmp_path / "padded.stl"  # longer than its header says
    padded.write_bytes(whole + b"\0" * 50)
    with pytest.raises(MeshError, match="holds more than its header says"):
        read_mesh_arrays(padded)


def test_an_ascii_stl_cut_short_is_named_as_such(tmp_path):
    # cut after its 5th facet, it was "no triangles (empty, points or lines only)"
    text = trimesh.exchange.stl.export_stl_ascii(trimesh.creation.box((10, 20, 30)))
    end = 0
    for _ in range(5):
        end = text.index("endfacet", end) + len("endfacet")
    cut = tmp_path / "cut.stl"
    cut.write_text(text[:end] + "\n")
    with pytest.raises(MeshError, match=r"cut\.stl' is not a whole STL file: it ends after 5 "
                                        r"whole facets without the 'endsolid' line.*add "
                                        r"'endsolid' as its last line"):
        load_mesh(cut)
    # the hint holds: a whole file whose writer left the line out reads once it is added
    (tmp_path / "closed.stl").write_text(text[:text.rindex("endsolid")] + "endsolid\n")
    assert len(read_mesh_arrays(tmp_path / "closed.stl")[1]) == 12
    # a file cut inside a facet says so too, with the facets before it
    inside = tmp_path / "inside.stl"
    inside.write_text(text[:end + 40])
    with pytest.raises(MeshError, match="ends after 5 whole facets"):
        read_mesh_arrays(inside)


def test_ascii_stl_line_ends_and_solids_are_read_whole(tmp_path):
    # lines ending in a carriage return alone (classic Mac), or a file on one line, read
    # as 1 triangle of a 12-triangle box (then failed as open); two solids (one per body,
    # as CAD tools write) were not read; a second solid cut short read as the first
    box = trimesh.creation.box((10, 20, 30))
    text = trimesh.exchange.stl.export_stl_ascii(box)
    moved = trimesh.exchange.stl.export_stl_ascii(box.copy().apply_translation([50, 0, 0]))
    named = text.replace("solid", "solid outer vertex shell", 1)  # keywords in its name
    for name, data in (("cr.stl", text.replace("\n", "\r")), ("line.stl", text.replace("\n", " ")),
                       ("upper.stl", text.upper()), ("named.stl", named.replace("\n", "\r")),
                       ("named-lf.stl", named), ("named-line.stl", named.replace("\n", " "))):
        (tmp_path / name).write_text(data, newline="")
        v, f = read_mesh_arrays(tmp_path / name)
        assert len(f) == 12 and load_mesh(tmp_path / name).volume == pytest.approx(6000.0), name
    (tmp_path / "two.stl").write_text(text + "\n" + moved)
    v, f = read_mesh_arrays(tmp_path / "two.stl")
    assert len(f) == 24 and v[f[12:]].mean(axis=(0, 1)) == pytest.approx([50.0, 0.0, 0.0])
    (tmp_path / "two-cut.stl").write_text((text + "\n" + moved)[:-300])
    with pytest.raises(MeshError, match="ends after 21 whole facets"):
        read_mesh_arrays(tmp_path / "two-cut.stl")


def test_obj_spacing_that_trimesh_misreads_reads_whole(tmp_path):
    # tabs between fields or indented lines read as no triangles, some indented face lines
    # as faces lost (a hole the user was told to fill), a byte order mark as a damaged file
    box = trimesh.creation.box((10, 20, 30))
    text = trimesh.exchange.obj.export_obj(box)
    lines = text.splitlines()
    faces = [i for i, line in enumerate(lines) if line.startswith("f ")]
    partial = list(lines)
    for i in faces[:3]:
        partial[i] = "\t" + partial[i]
    variants = {"tabs.obj": text.replace(" ", "\t"),
                "indented.obj": "\n".join("  " + line for line in lines),
                "partial.obj": "\n".join(partial),
                "bom.obj": "\ufeff" + text}
    for name, data in variants.items():
        (tmp_path / name).write_text(data, encoding="utf-8")
        v, f = read_mesh_arrays(tmp_path / name)
        assert len(f) == 12, name
        assert load_mesh(tmp_path / name).volume == pytest.approx(6000.0), name


def prism(sides: int) -> tuple[np.ndarray, list[list[int]]]:
    """A prism on a regular polygon of ``sides`` corners (radius 10, height 5), outward: its
    caps as single polygons, its sides as quads."""
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = np.column_stack([10 * np.cos(angle), 10 * np.sin(angle), np.zeros(sides)])
    polygons = [list(range(sides))[::-1], list(range(sides, 2 * sides))]
    polygons += [[i, (i + 1) % sides, sides + (i + 1) % sides, sides + i] for i in range(sides)]
    return np.vstack([ring, ring + [0.0, 0.0, 5.0]]), polygons


def prism_volume(sides: int) -> float:
    return 0.5 * sides * 100 * np.sin(2 * np.pi / sides) * 5


def off_lines(vertices: np.ndarray, polygons: list[list[int]]) -> list[str]:
    lines = ["OFF", f"{len(vertices)} {len(polygons)} 0"]
    lines += [f"{x!r} {y!r} {z!r}" for x, y, z in vertices]
    return lines + [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]


def ply_text(vertices: np.ndarray, polygons: list[list[int]]) -> str:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
             "property float x", "property float y", "property float z",
             f"element face {len(polygons)}", "property list uchar int vertex_indices",
             "end_header"]
    lines += [f"{x!r} {y!r} {z!r}" for x, y, z in vertices]
    return "\n".join(lines + [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]) + "\n"


def test_off_with_polygons_of_mixed_sizes_reads_as_its_ply_does(tmp_path):
    # a pentagonal prism (two pentagons, five quads) was refused: trimesh's OFF reader fails
    # on a mix of sizes with polygons over four corners, meshio reads triangles only
    for sides in (3, 5, 6):
        vertices, polygons = prism(sides)
        (tmp_path / f"p{sides}.off").write_text("\n".join(off_lines(vertices, polygons)))
        (tmp_path / f"p{sides}.ply").write_text(ply_text(vertices, polygons))
        v, f = read_mesh_arrays(tmp_path / f"p{sides}.off")
        assert len(f) == 2 * (sides - 2) + 2 * sides and np.allclose(v, vertices)
        mesh = load_mesh(tmp_path / f"p{sides}.off")
        assert_closed_oriented(mesh)
        assert mesh.volume == pytest.approx(prism_volume(sides))
        assert mesh.volume == pytest.approx(load_mesh(tmp_path / f"p{sides}.ply").volume)
    # what writers put around the numbers: comments, colours (per vertex with COFF, after
    # a face's corners), the counts on the keyword's line, no keyword, CRLF, 4OFF's
    # homogeneous coordinate
    lines = off_lines(*prism(5))
    whole = read_mesh_arrays(tmp_path / "p5.off")
    variants = {
        "comments": ["# made by hand", lines[0], lines[1] + "  # vertices faces edges",
                     *lines[2:4], "", "# the rest", *lines[4:9] + [lines[9] + " # cap"],
                     *lines[10:]],
        "colours": [*lines[:9], lines[9] + " 255 0 0", lines[10] + " 0.5 0.5 0.5 1",
                    lines[11] + " 3", *lines[12:]],
        "coff": ["COFF", lines[1], *(v + " 0.1 0.2 0.3 1" for v in lines[2:12]), *lines[12:]],
        "same-line": ["OFF " + lines[1], *lines[2:]],
        "no-keyword": lines[1:],
        "crlf": lines,
        "4off": ["4OFF", lines[1], *(" ".join(f"{2 * float(x)!r}" for x in v.split()) + " 2"
                                     for v in lines[2:12]), *lines[12:]],
    }
    for name, text in variants.items():
        path = tmp_path / f"{name}.off"
        path.write_bytes(("\r\n" if name == "crlf" else "\n").join(text).encode())
        v, f = read_mesh_arrays(path)
        assert np.allclose(v, whole[0]) and np.array_equal(f, whole[1]), name


def test_a_broken_off_names_the_line_and_what_is_wrong(tmp_path):
    # a file cut short read as the faces it held (a triangular prism cut after its 4th
    # face: two faces lost, then "a hole to fill"); the other damage was refused without
    # the line or the fix
    lines = off_lines(*prism(3))  # 6 vertices (lines 3-8), 5 faces (lines 9-13)

    def refused(name: str, text: list[str]) -> str:
        path = tmp_path / name
        path.write_text("\n".join(text) + "\n")
        with pytest.raises(MeshError) as info:
            read_mesh_arrays(path)
        message = str(info.value)
        assert f"'{path}'" in message and "xport it" in message, message  # what, and a fix
        return message

    message = refused("cut.off", lines[:12])
    assert "not a whole OFF file" in message
    assert "line 2 promise 6 vertices and 5 faces" in message
    assert "holds 10 lines of them" in message
    assert "cut short" in refused("few.off", lines[:6])
    assert "line 6 (vertex 4 of 6)" in refused("short-vertex.off", lines[:5] + ["1.0 2.0"]
                                                 + lines[6:])
    assert "'1.0 2.0'" in refused("short-vertex2.off", lines[:5] + ["1.0 2.0"] + lines[6:])
    message = refused("index.off", lines[:11] + ["4 1 2 6 4"] + lines[12:])
    assert "line 12 (face 4 of 5)" in message and "vertex 6" in message
    assert "0 to 5" in message
    assert "vertex -1" in refused("negative.off", lines[:11] + ["4 1 2 -1 4"] + lines[12:])
    assert "not a vertex index" in refused("float.off", lines[:11] + ["4 1 2 5.0 4"]
                                           + lines[12:])
    assert "line 10 (face 2 of 5)" in refused("corners.off", lines[:9] + ["4 3 4 5"]
                                               + lines[10:])
    assert "'2 0 1'" in refused("two.off", lines[:8] + ["2 0 1"] + lines[9:])
    message = refused("extra.off", lines + ["3 0 1 2"])
    assert "1 more face after them" in message
    assert "binary" in refused("binary.off", ["OFF BINARY", "6 5 0"])
    assert "line 1" in refused("counts.off", ["OFF six five"] + lines[2:])
    # a file whose last lines are blank or comments still reads
    (tmp_path / "tail.off").write_text("\n".join(lines) + "\n\n# end\n\n")
    assert len(read_mesh_arrays(tmp_path / "tail.off")[1]) == 8


@pytest.mark.parametrize("name, edit", [
    # ModelNet's files glue the first count to the keyword; trimesh read them
    ("modelnet", lambda lines: ["OFF" + lines[1]] + lines[2:]),
    ("lower-case keyword", lambda lines: ["off"] + lines[1:]),
    # after the faces: edges some writers list, a word, NUL or Ctrl-Z padding
    ("edges listed", lambda lines: lines + ["2 0 1", "2 1 2"]),
    ("a last word", lambda lines: lines + ["end"]),
    ("NUL padding", lambda lines: lines + ["\x00\x00"]),
    ("Ctrl-Z padding", lambda lines: lines + ["\x1a"]),
    # numbers after a face's corners: a colour, and more than a colour's four
    ("face colours", lambda lines: lines[:8] + [f"{f} 0.1 0.2 0.3 1.0 7" for f in lines[8:]]),
])
def test_off_files_trimesh_read_still_read(tmp_path, name, edit):
    """A review of the OFF reader found these refused where trimesh had read them."""
    lines = off_lines(*prism(3))
    path = tmp_path / "prism.off"
    path.write_text("\n".join(edit(lines)) + "\n")
    v, f = read_mesh_arrays(path)
    assert len(v) == 6 and len(f) == 8, name



def test_an_ascii_ply_cut_short_is_named_as_such(tmp_path):
    # an ASCII PLY whose header promises more than it holds read as what it holds: a box
    # cut after 10 of its 12 faces gave 10 triangles, then "a hole to fill"
    box = trimesh.creation.box((10, 20, 30))
    text = trimesh.exchange.ply.export_ply(box, encoding="ascii")
    body = text.splitlines(keepends=True)
    for name, data in (("whole.ply", text), ("crlf.ply", text.replace(b"\n", b"\r\n")),
                       ("blank-tail.ply", text + b"\n\n  \n"),
                       ("binary.ply", trimesh.exchange.ply.export_ply(box))):
        (tmp_path / name).write_bytes(data)
        assert len(read_mesh_arrays(tmp_path / name)[1]) == 12, name
        assert load_mesh(tmp_path / name).volume == pytest.approx(6000.0), name
    # polygons of mixed sizes, and elements the header lists that are not read (edges)
    vertices, polygons = prism(5)
    mixed = ply_text(vertices, polygons).replace(
        "end_header", "element edge 2\nproperty int vertex1\nproperty int vertex2\nend_header")
    (tmp_path / "mixed.ply").write_text(mixed + "0 1\n1 2\n")
    assert load_mesh(tmp_path / "mixed.ply").volume == pytest.approx(prism_volume(5))

    def refused(name: str, data: bytes) -> str:
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(MeshError) as info:
            read_mesh_arrays(path)
        message = str(info.value)
        assert f"'{path}' is not a whole PLY file" in message, message
        assert "export it again" in message, message
        return message

    message = refused("cut.ply", b"".join(body[:-2]))
    assert "its header promises 8 vertices and 12 faces" in message and "cut short" in message
    assert "holds 8 vertices and 10 faces" in message
    message = refused("mid-line.ply", text[:-5])  # cut inside its last face's line
    assert "holds 8 vertices and 11 faces (and part of one more)" in message
    message = refused("vertices.ply", b"".join(body[:-15]))
    assert "holds 5 vertices and no faces" in message
    message = refused("longer.ply", text + b"3 0 1 2\n")
    assert "1 more line" in message
    # NUL or Ctrl-Z padding at the end is not a line (trimesh read such files)
    assert len(read_mesh_arrays(_written(tmp_path / "padded.ply", text + b"\x00\x00\n\x1a"))[1]) \
        == 12
    # a binary PLY whose header comment says "format ascii" is binary all the same
    binary = trimesh.creation.box().export(file_type="ply", encoding="binary")
    tricky = binary.replace(b"format binary", b"comment format ascii\nformat binary", 1)
    assert len(read_mesh_arrays(_written(tmp_path / "comment.ply", tricky))[1]) == 12


def _written(path, data: bytes):
    path.write_bytes(data)
    return path


def binary_ply(vertices: np.ndarray, polygons: list[list[int]]) -> bytes:
    """A binary PLY as Blender writes one: float x y z, faces as ``list uchar uint``."""
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {len(vertices)}",
            "property float x", "property float y", "property float z",
            f"element face {len(polygons)}", "property list uchar uint vertex_indices",
            "end_header"]
    body = np.asarray(vertices, "<f4").tobytes()
    body += b"".join(np.uint8(len(p)).tobytes() + np.asarray(p, "<u4").tobytes()
                     for p in polygons)
    return ("\n".join(head) + "\n").encode() + body


def test_a_binary_ply_with_polygons_of_mixed_sizes_reads_whole(tmp_path):
    # Blender's binary PLY of a cylinder with n-gon caps: trimesh refuses lists of mixed
    # lengths ("PLY is unexpected length!"), then meshio's 'polygon' blocks were dropped:
    # the caps were lost, silently
    for sides in (5, 12):
        vertices, polygons = prism(sides)
        v, f = read_mesh_arrays(_written(tmp_path / f"p{sides}.ply",
                                         binary_ply(vertices, polygons)))
        assert len(f) == 2 * (sides - 2) + 2 * sides and np.allclose(v, vertices)
        mesh = load_mesh(tmp_path / f"p{sides}.ply")
        assert_closed_oriented(mesh)
        assert mesh.volume == pytest.approx(prism_volume(sides), rel=1e-6)


@pytest.mark.parametrize("ext", ["vtk", "vtu", "msh", "mesh"])
def test_meshio_formats_with_quads_and_polygons_read_whole(tmp_path, ext):
    # trimesh claims these formats but reads them through meshio keeping triangles only: a
    # cube of quads read as "no triangles", a mixed one with holes, polygons were dropped
    import meshio

    vertices, polygons = prism(4)
    quads = np.array(polygons)
    tris = np.array([t for q in quads[2:] for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])
    cases = {"quads": [("quad", quads)], "mixed": [("triangle", tris), ("quad", quads[:2])]}
    if ext in ("vtk", "vtu"):  # the formats with general polygons
        v6, p6 = prism(6)
        cases["polygons"] = (v6, [("quad", np.array(p6[2:])), ("polygon", np.array(p6[:2]))])
    for name, cells in cases.items():
        points, cells = cells if isinstance(cells, tuple) else (vertices, cells)
        path = tmp_path / f"{name}.{ext}"
        meshio.write(path, meshio.Mesh(points, cells))
        mesh = load_mesh(path)
        assert_closed_oriented(mesh)
        sides = 6 if name == "polygons" else 4
        assert mesh.volume == pytest.approx(prism_volume(sides), rel=1e-6), (name, ext)


def test_meshio_cells_that_are_not_read_are_named(tmp_path):
    # volume cells only (a tetrahedral mesh without its boundary): no surface to read
    import meshio

    path = tmp_path / "tets.vtu"
    meshio.write(path, meshio.Mesh(np.eye(4, 3), [("tetra", np.array([[0, 1, 2, 3]]))]))
    with pytest.raises(MeshError, match=r"tets\.vtu' holds volume cells only \(tetra\)"):
        read_mesh_arrays(path)


def _glb_with(glb: bytes, edit) -> bytes:
    """``glb`` with its JSON chunk changed by ``edit(document)``."""
    import json

    size = int.from_bytes(glb[12:16], "little")
    document = json.loads(glb[20:20 + size])
    edit(document)
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    rest = glb[20 + size:]
    chunk = len(text).to_bytes(4, "little") + b"JSON" + text
    return glb[:8] + (12 + len(chunk) + len(rest)).to_bytes(4, "little") + chunk + rest


def test_a_draco_compressed_gltf_is_refused_by_name(tmp_path):
    # a Draco-compressed GLB (Blender's glTF export, Compression on) read as placeholder
    # zeros: "zero volume" or hundreds of degenerate bodies, trimesh's warning on stderr
    glb = trimesh.creation.box(extents=(10, 10, 10)).export(file_type="glb")
    assert len(read_mesh_arrays(_written(tmp_path / "plain.glb", glb))[1]) == 12

    def draco(document: dict) -> None:
        document["extensionsUsed"] = ["KHR_draco_mesh_compression"]
        document["extensionsRequired"] = ["KHR_draco_mesh_compression"]
        document["meshes"][0]["primitives"][0]["extensions"] = {
            "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}

    def primitive_only(document: dict) -> None:
        draco(document)
        del document["extensionsUsed"], document["extensionsRequired"]

    for name, edit in (("draco.glb", draco), ("primitive.glb", primitive_only)):
        with pytest.raises(MeshError, match=r"is a Draco-compressed glTF, which is not read: "
                           r"export it again without mesh compression \(Blender"):
            read_mesh_arrays(_written(tmp_path / name, _glb_with(glb, edit)))


def test_a_gltf_without_its_buffer_file_names_it(tmp_path):
    # a .gltf whose .bin is not beside it: trimesh's error was the bare file name, and the
    # message said "damaged or not really .gltf"
    files = trimesh.creation.box().export(file_type="gltf")
    for name, blob in files.items():
        (tmp_path / name).write_bytes(blob)
    assert len(read_mesh_arrays(tmp_path / "model.gltf")[1]) == 12
    (tmp_path / "gltf_buffer_0.bin").unlink()
    with pytest.raises(MeshError, match=r"model\.gltf' keeps its data in the buffer file "
                       r"'gltf_buffer_0\.bin', which is missing"):
        read_mesh_arrays(tmp_path / "model.gltf")


def test_a_file_with_a_missing_or_wrong_extension_says_what_it_looks_like(tmp_path):
    # no extension read as "unknown file type '.'"; a 3MF renamed .stl as "its header says
    # 2,655,588,004 triangles"; a binary STL or GLB renamed .obj as "no triangles"
    box = trimesh.creation.box(extents=(10, 10, 10))
    blobs = {"stl": box.export(file_type="stl"), "3mf": box.export(file_type="3mf"),
             "glb": box.export(file_type="glb"), "obj": box.export(file_type="obj").encode(),
             "ply": box.export(file_type="ply", encoding="ascii"),
             "off": "\n".join(off_lines(*prism(5))).encode(),
             "ascii-stl": box.export(file_type="stl_ascii").encode()}
    for kind, blob in blobs.items():  # each read whole under its own name
        ext = kind.removeprefix("ascii-")
        assert len(read_mesh_arrays(_written(tmp_path / f"{kind}.{ext}", blob))[1]) > 0

    def refused(name: str, kind: str) -> str:
        with pytest.raises(MeshError) as info:
            read_mesh_arrays(_written(tmp_path / name, blobs[kind]))
        return str(info.value)

    for name, kind, what in [
        ("noext", "stl", "has no file extension, and it looks like a binary STL file"),
        ("box3mf.stl", "3mf", "looks like a 3MF file (a zip with 3D/3dmodel.model), not STL"),
        ("boxobj.stl", "obj", "looks like an OBJ file ('v' and 'f' lines), not STL"),
        ("boxstl.obj", "stl", "looks like a binary STL file"),
        ("boxglb.obj", "glb", "looks like a GLB file"),
        ("boxascii.obj", "ascii-stl", "looks like an ASCII STL file"),
        ("boxply.off", "ply", "looks like a PLY file ('ply' on its first line), not OFF"),
        ("boxoff.ply", "off", "looks like an OFF file ('OFF' on its first line), not PLY"),
        ("boxstl.3mf", "stl", "looks like a binary STL file"),
    ]:
        message = refused(name, kind)
        ext = kind.removeprefix("ascii-")
        assert f"'{tmp_path / name}' {what}" in message and f"rename it to .{ext}." in message, \
            message
    # no extension and nothing recognised: said so, not "unknown file type '.'"
    with pytest.raises(MeshError, match=r"noise' has no file extension \(no reader for it\)"):
        read_mesh_arrays(_written(tmp_path / "noise", b"\x01\x02 not a mesh\n"))


def test_concave_polygons_read_through_meshio_are_ear_clipped(tmp_path):
    # an L-shaped prism with its caps as single polygons, as a binary PLY (read by meshio)
    # and a VTK: a fan from the first corner of a concave cap makes faces that cross
    import meshio

    outline = np.array([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]], float)
    bottom = np.column_stack([outline, np.zeros(6)])
    vertices = np.vstack([bottom, bottom + [0.0, 0.0, 5.0]])
    polygons = [list(range(6))[::-1], list(range(6, 12))]
    polygons += [[i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    meshio.write(tmp_path / "l.vtk", meshio.Mesh(vertices, [
        ("quad", np.array(polygons[2:])), ("polygon", np.array(polygons[:2]))]))
    for path in (_written(tmp_path / "l.ply", binary_ply(vertices, polygons)),
                 tmp_path / "l.vtk"):
        v, f = read_mesh_arrays(path)
        solid = manifold3d.Manifold(manifold3d.Mesh(v.astype(np.float32), f.astype(np.uint32)))
        assert solid.status() == manifold3d.Error.NoError, path
        assert solid.volume() == pytest.approx(1500.0) and solid.surface_area() == \
            pytest.approx(2 * 300 + 5 * 80), path
    # convex quads are split as before polygons were read: first triangles, then second ones
    quads = np.array(polygons[2:])
    meshio.write(tmp_path / "sides.vtu", meshio.Mesh(vertices, [("quad", quads)]))
    assert np.array_equal(read_mesh_arrays(tmp_path / "sides.vtu")[1],
                          np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))


def test_noff_stays_refused_by_name_and_gltf_nulls_are_mesh_errors(tmp_path):
    """A review found nOFF read past its keyword once the keyword matched any case ('line 2
    should hold the counts'), and a glTF whose extensionsUsed, meshes or primitives were
    null raised a bare TypeError from the Draco check."""
    (tmp_path / "n.off").write_text("nOFF\n3\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    with pytest.raises(MeshError, match=r"line 1 starts with 'nOFF' \(vertices of any "):
        read_mesh_arrays(tmp_path / "n.off")
    box = trimesh.creation.box()
    for key, path in (("extensionsUsed", ()), ("meshes", ()), ("primitives", ("meshes", 0))):
        glb = trimesh.exchange.gltf.export_gltf(trimesh.Scene(box))
        doc = json.loads(glb["model.gltf"])
        holder = doc
        for step in path:
            holder = holder[step]
        holder[key] = None
        folder = tmp_path / key
        folder.mkdir()
        for name, data in glb.items():
            (folder / name).write_bytes(json.dumps(doc).encode() if name == "model.gltf"
                                        else data)
        try:
            read_mesh_arrays(folder / "model.gltf")
        except MeshError:
            pass  # a damaged file, named as such: what is asked


@pytest.mark.parametrize("keyword, read", [
    ("coff", True), ("stoff", True), ("Coff", True), ("NOFF", True), ("OFF3", True),
    ("nOFF", False), ("4nOFF", False)])
def test_off_keywords_in_any_case(tmp_path, keyword, read):
    """Only OFF's own letters matched any case for a while: coff and stoff, which read
    before, were refused. A lower-case n just before OFF is the dimension line's; a count
    may be glued to the keyword (OFF3, as ModelNet writes it)."""
    counts = " 1 0\n" if keyword[-1].isdigit() else "\n3 1 0\n"
    extra = {"c": " 1 0 0 1", "s": " 0 0"}.get(keyword[0].lower(), "")
    text = keyword + counts + "".join(f"{x}{extra}\n" for x in ("0 0 0", "1 0 0", "0 1 0"))
    (tmp_path / "k.off").write_text(text + "3 0 1 2\n")
    if read:
        assert len(read_mesh_arrays(tmp_path / "k.off")[1]) == 1
    else:
        with pytest.raises(MeshError, match="vertices of any dimension"):
            read_mesh_arrays(tmp_path / "k.off")


def test_obj_relative_indices_count_back_from_their_line(tmp_path):
    # -1 is the last vertex defined before the face line (trimesh counts from the file's
    # end): with each face written after its own corners, a wrong count gives other faces
    box = trimesh.creation.box((10, 20, 30))
    lines = []
    for face in box.faces:
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in box.vertices[face]]
        lines.append("f -3 -2 -1")
    variants = {"relative.obj": "\n".join(lines),
                "indented.obj": "\n".join("  " + line for line in lines),
                "slashes.obj": "\n".join(["vn 0 0 1"] + [
                    line.replace("f -3 -2 -1", "f -3//-1 -2//-1 -1//-1") for line in lines])}
    for name, text in variants.items():
        (tmp_path / name).write_text(text)
        v, f = read_mesh_arrays(tmp_path / name)
        assert len(f) == 12, name
        np.testing.assert_allclose(v[f], box.vertices[box.faces], err_msg=name)
        assert load_mesh(tmp_path / name).volume == pytest.approx(6000.0), name


def _manifold_of(path) -> manifold3d.Manifold:
    v, f = read_mesh_arrays(path)
    return manifold3d.Manifold(manifold3d.Mesh(v.astype(np.float32), f.astype(np.uint32)))


def test_concave_polygons_of_binary_ply_and_of_a_singular_face_list_are_cut_right(tmp_path):
    # a binary PLY whose faces are all quads, two of them darts (concave), kept trimesh's fan
    # from the first corner; a face list named vertex_index (trimesh reads it, meshio does
    # not) kept the fan in ASCII, and was refused in binary with mixed sizes
    dart = np.array([[0, 0], [20, 2], [0, 20], [5, 5]], float)  # reflex at its last corner
    vertices, polygons = prism(4)
    vertices[:4, :2], vertices[4:, :2] = dart, dart
    files = {"darts.ply": binary_ply(vertices, polygons)}
    outline = np.array([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]], float)
    l_vertices = np.vstack([np.column_stack([outline, np.full(6, z)]) for z in (0.0, 5.0)])
    l_polygons = [list(range(6))[::-1], list(range(6, 12))]
    l_polygons += [[i, (i + 1) % 6, 6 + (i + 1) % 6, 6 + i] for i in range(6)]
    files["l-ascii.ply"] = ply_text(l_vertices, l_polygons).encode()
    files["l-binary.ply"] = binary_ply(l_vertices, l_polygons)
    files["darts-singular.ply"] = files["darts.ply"]
    areas = {"darts": 2 * 150.0, "l": 2 * 300.0}  # the caps' (shoelace)
    for name, data in files.items():
        if name != "darts.ply":
            data = data.replace(b"vertex_indices\n", b"vertex_index\n")
        path = _written(tmp_path / name, data)
        solid = _manifold_of(path)
        assert solid.status() == manifold3d.Error.NoError, name
        area = areas[name.split("-")[0].split(".")[0]]
        assert solid.volume() == pytest.approx(area / 2 * 5), name
        top = trimesh.Trimesh(*read_mesh_arrays(path), process=False)
        caps = np.abs(top.face_normals[:, 2]) > 0.5
        assert top.area_faces[caps].sum() == pytest.approx(area), name  # no face folded over
