"""A file's polygons as triangles: convex ones fanned as before, concave ones ear-clipped in
their plane (a fan from the first corner makes faces that cross)."""

from __future__ import annotations

import manifold3d
import numpy as np
import pytest
import trimesh

from jampacked.core.meshes import load_mesh
from jampacked.core.polygons import concave, fan, polygons_to_triangles

#: an L (area 300) and a five-pointed star, counter-clockwise, in the xy plane
L_SHAPE = np.array([[0, 0], [20, 0], [20, 10], [10, 10], [10, 20], [0, 20]], float)
_ANGLES = np.pi / 2 + np.arange(10) * np.pi / 5
STAR = np.column_stack([np.where(np.arange(10) % 2, 4.0, 10.0) * np.cos(_ANGLES),
                        np.where(np.arange(10) % 2, 4.0, 10.0) * np.sin(_ANGLES)])


def extruded(outline: np.ndarray, height: float = 5.0) -> tuple[np.ndarray, list[list[int]]]:
    """A prism on ``outline`` (CCW): its caps as single polygons, its sides as quads."""
    n = len(outline)
    bottom = np.column_stack([outline, np.zeros(n)])
    vertices = np.vstack([bottom, bottom + [0.0, 0.0, height]])
    polygons = [list(range(n))[::-1], list(range(n, 2 * n))]
    polygons += [[i, (i + 1) % n, n + (i + 1) % n, n + i] for i in range(n)]
    return vertices, polygons


def shoelace(outline: np.ndarray) -> float:
    x, y = outline.T
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def _flat(polygons):
    return np.array([len(p) for p in polygons]), np.concatenate(polygons)


def fan_reference(sizes, corners):
    """Each polygon fanned from its first corner, written out the obvious way."""
    out, at = [], 0
    for size in sizes:
        ring = corners[at:at + size]
        out += [[ring[0], ring[k], ring[k + 1]] for k in range(1, size - 1)]
        at += size
    return np.array(out)


@pytest.mark.parametrize("outline", [L_SHAPE, STAR, L_SHAPE[::-1][np.r_[3:6, 0:3]]],
                         ids=["L", "star", "L turned"])
def test_a_concave_prism_is_a_sound_solid_of_its_volume(outline):
    if shoelace(outline) < 0:
        outline = outline[::-1]
    vertices, polygons = extruded(outline)
    sizes, corners = _flat(polygons)
    assert concave(vertices, sizes, corners).tolist() == [True, True] + [False] * len(outline)
    faces = polygons_to_triangles(vertices, sizes, corners)
    assert len(faces) == sum(sizes - 2)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(5.0 * shoelace(outline), rel=1e-12)
    m = manifold3d.Manifold(manifold3d.Mesh(vertices.astype(np.float32), faces.astype(np.uint32)))
    assert m.status() == manifold3d.Error.NoError
    assert m.volume() == pytest.approx(mesh.volume, rel=1e-6)
    # the fan folds back over its cap (a triangle facing against the cap), so its faces
    # cross: the reason for all this; ear clipping keeps every triangle facing outward
    cap_faces = sizes[0] - 2 + sizes[1] - 2

    def against(tris):
        normals = trimesh.Trimesh(vertices, tris[:cap_faces], process=False).face_normals
        return int((normals[:, 2] * np.repeat([-1.0, 1.0], cap_faces // 2) < 0).sum())

    assert against(fan_reference(sizes, corners)) > 0
    assert against(faces) == 0


def test_convex_polygons_are_fanned_exactly_as_before():
    rng = np.random.default_rng(3)
    angle = np.sort(rng.uniform(0, 2 * np.pi, 9))
    outline = np.column_stack([np.cos(angle), np.sin(angle)]) * 7.0  # convex, uneven
    vertices, polygons = extruded(outline)
    sizes, corners = _flat(polygons)
    assert not concave(vertices, sizes, corners).any()
    np.testing.assert_array_equal(polygons_to_triangles(vertices, sizes, corners),
                                  fan_reference(sizes, corners))
    at, polygon = fan(sizes)
    np.testing.assert_array_equal(corners[at], fan_reference(sizes, corners))
    assert polygon.tolist() == np.repeat(np.arange(len(sizes)), sizes - 2).tolist()


def test_corners_on_a_line_do_not_make_a_polygon_concave():
    square = np.array([[0, 0], [5, 0], [10, 0], [10, 10], [0, 10]], float)  # a straight corner
    vertices, polygons = extruded(square)
    assert not concave(vertices, *_flat(polygons)).any()


def test_concave_polygons_of_obj_off_and_ply_files_read_as_solids(tmp_path):
    """An L-shaped prism as Blender writes it (OBJ with n-gons, normals; not triangulated)
    read with its caps fanned: 'self-intersecting (17 face pairs)' in validate, and pack
    took it as a type whose parts export then failed. The STL of the same solid passed.
    trimesh fans an ASCII PLY's polygons too."""
    vertices, polygons = extruded(L_SHAPE)
    normals = "vn 0 0 -1\nvn 0 0 1\n"
    obj = "o L\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + normals
    obj += "s 0\n" + "".join("f " + " ".join(f"{i + 1}//{1 if k == 0 else 2}" for i in p)
                             + "\n" for k, p in enumerate(polygons))
    off = ["OFF", f"{len(vertices)} {len(polygons)} 0"]
    off += [f"{x} {y} {z}" for x, y, z in vertices]
    off += [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]
    ply = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}", "property float x",
           "property float y", "property float z", f"element face {len(polygons)}",
           "property list uchar int vertex_indices", "end_header"]
    ply += [f"{x} {y} {z}" for x, y, z in vertices]
    ply += [f"{len(p)} " + " ".join(map(str, p)) for p in polygons]
    (tmp_path / "L.obj").write_text(obj)
    (tmp_path / "L.off").write_text("\n".join(off) + "\n")
    (tmp_path / "L.ply").write_text("\n".join(ply) + "\n")
    for name in ("L.obj", "L.off", "L.ply"):
        mesh = load_mesh(tmp_path / name)
        assert mesh.volume == pytest.approx(1500.0, rel=1e-9), name
        m = manifold3d.Manifold(manifold3d.Mesh(mesh.vertices.astype(np.float32),
                                                mesh.faces.astype(np.uint32)))
        assert m.status() == manifold3d.Error.NoError, name
        from jampacked.export.validate import validate_file
        assert validate_file(tmp_path / name).passed, name


def _written_read(tmp_path, name: str, text: str):
    from jampacked.core.mesh_files import read_mesh_arrays

    (tmp_path / name).write_text(text)
    v, f = read_mesh_arrays(tmp_path / name)
    return float(trimesh.Trimesh(v, f, process=False).area)


#: one L-shaped face (area 3) whose first corner does not see the reflex one
_L = [(2, 1), (1, 1), (1, 2), (0, 2), (0, 0), (2, 0)]


@pytest.mark.parametrize("name, text", [
    ("repeated corner.obj", "".join(f"v {x} {y} 0\n" for x, y in _L) + "f 1 2 2 3 4 5 6\n"),
    ("coincident corner.obj", "".join(f"v {x} {y} 0\n" for x, y in _L)
     + "v 1 1 0\nf 1 2 7 3 4 5 6\n"),
    ("vertex colours.obj", "".join(f"v {x} {y} 0 1 0 0\n" for x, y in _L)
     + "f 1 2 3 4 5 6\n"),
    ("repeated corner.off", "OFF\n6 1 0\n" + "".join(f"{x} {y} 0\n" for x, y in _L)
     + "7 0 1 1 2 3 4 5\n"),
])
def test_concave_faces_a_review_found_still_fanned_are_cut_right(tmp_path, name, text):
    """A repeated corner (or two at one place) hid the reflex turn, and an OBJ with vertex
    colours was left to trimesh: each read with the fan's area, 4."""
    assert _written_read(tmp_path, name, text) == pytest.approx(3.0)


def test_concave_quads_are_fanned_from_their_reflex_corner():
    """A dart (a concave quad) is cut from its one reflex corner, without ear clipping (50,000
    of them took 4.8 s one by one): the same triangles, and its area."""
    dart = np.array([[0, 0, 0], [4, 0, 0], [1, 1, 0], [0, 4, 0]], float)
    vertices = np.vstack([dart + [10.0 * i, 0, 0] for i in range(3)])
    rolls = [np.roll(np.arange(4), -k) + 4 * i for i, k in enumerate((0, 1, 3))]
    sizes, corners = np.full(3, 4), np.concatenate(rolls)
    assert concave(vertices, sizes, corners).all()
    faces = polygons_to_triangles(vertices, sizes, corners)
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    assert mesh.area == pytest.approx(3 * 4.0)  # each dart: 4 (shoelace)
    assert (mesh.face_normals[:, 2] > 0).all()


def test_a_quad_padding_a_triangle_is_fanned_and_a_polygon_of_no_area_warns_nothing():
    """A review found "quads" that repeat a corner (some writers pad triangles so) flagged
    and ear-clipped one by one (85 s a million), and a polygon whose corners lie on a line
    divided by its zero normal (a RuntimeWarning, NaNs to the triangulator)."""
    import warnings

    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0]], float)
    padded = np.array([0, 1, 2, 2])
    assert not concave(vertices, np.array([4]), padded).any()
    assert polygons_to_triangles(vertices, np.array([4]), padded).tolist() == [[0, 1, 2],
                                                                              [0, 2, 2]]
    on_a_line = np.array([0, 1, 1, 3, 4])  # five corners on the x axis, one repeated
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        faces = polygons_to_triangles(vertices, np.array([5]), on_a_line)
    assert len(faces) == 3 and set(faces.ravel()) <= set(on_a_line)


@pytest.mark.parametrize("k", [4, 5, 7])
def test_polygons_of_one_size_are_judged_as_the_general_path_judges_them(k):
    """All polygons of one size take a path on (P, k) arrays: the same answer, bit for bit,
    as the general path (forced here by one triangle more) on random, planar, near-flat and
    repeated-corner polygons."""
    rng = np.random.default_rng(k)
    n = 3000
    angles = np.sort(rng.uniform(0, 2 * np.pi, (n, k)), axis=1)
    cases = [rng.normal(size=(n * k, 3)),
             np.column_stack([rng.normal(size=(n * k, 2)), np.zeros(n * k)]),
             np.stack([np.cos(angles), np.sin(angles),
                       1e-9 * rng.normal(size=(n, k))], -1).reshape(-1, 3)]
    cases[2][::7] = cases[2][1::7]
    seen = set()
    for points in cases:
        sizes, corners = np.full(n, k), np.arange(n * k)
        one_size = concave(points, sizes, corners)
        general = concave(points, np.append(sizes, 3), np.append(corners, [0, 1, 2]))[:-1]
        assert np.array_equal(one_size, general)
        seen |= set(one_size.tolist())
    assert seen == {True, False}
