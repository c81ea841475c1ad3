"""Tests for jampacked.export.validate, export.io and `jampacked validate`.

Test meshes are built with trimesh.creation and manifold3d (small: the whole file runs in
seconds once numba's cache is warm), plus the broken files of tests/data/meshes/broken.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import manifold3d
import meshio
import numpy as np
import pytest
import trimesh
from testdata import MESHES, mesh_path

from jampacked.cli.main import main
from jampacked.core.errors import InputError, MeshError
from jampacked.export import intersect
from jampacked.export.io import read_mesh_arrays, write_mesh
from jampacked.export.validate import ValidationReport, validate_arrays, validate_file
from jampacked.export.validation_topology import merge_identical


def box(extents=(2.0, 3.0, 4.0), offset=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    m = trimesh.creation.box(extents=extents)
    return np.array(m.vertices) + offset, np.array(m.faces)


def concat(*bodies: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, n = [], [], 0
    for v, f in bodies:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return np.concatenate(vs), np.concatenate(fs)


def edge_set(pairs: np.ndarray, vertices: np.ndarray) -> set:
    """Edges as unordered pairs of positions (independent of vertex numbering)."""
    return {frozenset(tuple(vertices[i]) for i in pair) for pair in np.asarray(pairs)}


# ------------------------------------------------------------------------------------------
# good meshes pass


def test_box_passes():
    v, f = box()
    r = validate_arrays(v, f)
    assert r.passed, r.summary()
    assert r.summary().startswith("PASS mesh: 1 body")
    (b,) = r.bodies
    assert b.volume == pytest.approx(24.0) and r.volume == pytest.approx(24.0)
    assert b.genus == 0 and b.kind == "solid" and b.closed and b.outward
    assert (b.faces, b.vertices, b.edges) == (12, 8, 18)
    assert b.bbox_min == pytest.approx((-1, -1.5, -2)) and b.bbox_max == pytest.approx((1, 1.5, 2))
    assert r.manifold_status == "NoError"
    assert all(len(a) == 0 for a in r.offending.values())


def test_icosphere_and_torus_genus():
    s = trimesh.creation.icosphere(subdivisions=3, radius=2.0)
    r = validate_arrays(s.vertices, s.faces)
    assert r.passed and r.bodies[0].genus == 0
    assert r.volume == pytest.approx(s.volume, rel=1e-12)
    t = trimesh.creation.torus(major_radius=2.0, minor_radius=0.5)
    r = validate_arrays(t.vertices, t.faces)
    assert r.passed, r.summary()
    assert r.bodies[0].genus == 1
    assert r.volume == pytest.approx(t.volume, rel=1e-12)


def test_manifold3d_output_genus_two():
    """A typical export: manifold3d booleans, arrays straight from manifold (no trimesh)."""
    block = manifold3d.Manifold.cube([6.0, 3.0, 2.0], center=True)
    hole = manifold3d.Manifold.cylinder(4.0, 0.8, 0.8, 32, center=True)
    solid = block - hole.translate([-1.5, 0, 0]) - hole.translate([1.5, 0, 0])
    mesh = solid.to_mesh()
    r = validate_arrays(mesh.vert_properties[:, :3], mesh.tri_verts)
    assert r.passed, r.summary()
    assert r.bodies[0].genus == 2
    assert r.volume == pytest.approx(solid.volume(), rel=1e-5)


def test_two_disjoint_boxes_are_two_bodies():
    r = validate_arrays(*concat(box(), box(offset=(5.0, 0, 0))))
    assert r.passed, r.summary()
    assert len(r.bodies) == 2 and [b.genus for b in r.bodies] == [0, 0]
    assert r.volume == pytest.approx(48.0)
    assert [b.bbox_min[0] for b in r.bodies] == pytest.approx([-1.0, 4.0])
    assert "2 bodies" in r.summary()


def test_hollow_solid_with_cavity_passes():
    outer = box((4, 4, 4))
    inner_v, inner_f = box((1, 1, 1))
    r = validate_arrays(*concat(outer, (inner_v, inner_f[:, ::-1])))
    assert r.passed, r.summary()
    assert [b.kind for b in r.bodies] == ["solid", "cavity"]
    assert r.bodies[1].inside == (0,)
    assert r.volume == pytest.approx(63.0)
    assert "1 body, 1 cavity" in r.summary()  # "2 bodies, 1 cavity" before


def test_stl_soup_is_merged_at_identical_positions_only():
    v, f = box()
    soup = v[f].reshape(-1, 3)
    r = validate_arrays(soup, np.arange(len(soup)).reshape(-1, 3))
    assert r.passed and r.n_vertices == 36 and r.n_positions == 8
    first, remap = merge_identical(np.array([[0.0, 0, 0], [-0.0, 0, 0], [1e-300, 0, 0]]))
    assert first.tolist() == [0, 2] and remap.tolist() == [0, 0, 1]


# ------------------------------------------------------------------------------------------
# meshes broken on purpose fail, for the right reason, naming the offending elements


def test_hole_is_found():
    v, f = box()
    r = validate_arrays(v, f[1:])
    assert not r.passed
    b = r.bodies[0]
    assert (b.open_edges, b.holes, b.kind, b.genus) == (3, 1, "open", None)
    assert edge_set(r.offending["open_edges"], v) == edge_set(
        [[f[0, 0], f[0, 1]], [f[0, 1], f[0, 2]], [f[0, 2], f[0, 0]]], v)
    assert "3 open edges around 1 hole" in r.summary()


def test_flipped_face_is_found():
    v, f = box()
    f = f.copy()
    f[5] = f[5, ::-1]
    r = validate_arrays(v, f)
    assert not r.passed
    b = r.bodies[0]
    assert b.inconsistent_edges == 3 and b.flipped_faces == 1 and b.orientable
    assert r.offending["flipped_faces"].tolist() == [5]
    assert "1 face wound against its neighbours" in r.summary()


def test_self_intersecting_body_is_found():
    """An icosphere with one vertex pushed through the opposite side: a spike that pierces
    the surface; still closed, consistently wound and of positive volume."""
    s = trimesh.creation.icosphere(subdivisions=2)
    v = np.array(s.vertices)
    v[0] *= -1.3
    r = validate_arrays(v, s.faces)
    assert not r.passed
    b = r.bodies[0]
    assert b.closed and b.inconsistent_edges == 0 and b.volume > 0 and b.kind == "solid"
    assert b.self_intersections > 0
    ring = set(np.flatnonzero((s.faces == 0).any(axis=1)))
    hit = set(r.offending["intersecting_faces"].tolist())
    assert ring <= hit
    assert all(p[0] in ring or p[1] in ring for p in r.offending["intersecting_pairs"])
    assert "self-intersecting" in r.summary()


def test_duplicate_face_is_found():
    v, f = box()
    r = validate_arrays(v, np.vstack([f, f[3:4]]))
    assert not r.passed
    b = r.bodies[0]
    assert b.duplicate_faces == 1 and b.nonmanifold_edges == 3
    assert r.offending["duplicate_faces"].tolist() == [12]
    # the copy is not reported as intersecting its original
    assert r.intersecting_pairs == 0


def test_inside_out_mesh_fails():
    v, f = box()
    r = validate_arrays(v, f[:, ::-1])
    assert not r.passed
    b = r.bodies[0]
    assert b.kind == "inside-out" and not b.outward and b.volume == pytest.approx(-24.0)
    assert b.inconsistent_edges == 0 and b.closed
    assert "inside out" in r.summary()


def test_zero_area_face_in_a_closed_mesh_is_degenerate():
    v, f = box()
    v = np.vstack([v, 0.5 * (v[0] + v[1])])  # m = 8, on edge 0-1
    a, b, c, d, m = 0, 1, 3, 4, 8
    assert {tuple(f[0]), tuple(f[1])} == {(1, 3, 0), (4, 1, 0)}  # (a b c) and (b a d)
    faces = np.vstack([f[2:], [[b, a, d], [a, m, c], [m, b, c], [b, m, a]]])
    r = validate_arrays(v, faces)
    body = r.bodies[0]
    assert body.closed and body.inconsistent_edges == 0
    assert body.degenerate_faces == 1 and r.offending["degenerate_faces"].tolist() == [13]
    assert not r.passed and "1 degenerate face" in r.summary()


def test_bodies_touching_at_a_vertex():
    r = validate_arrays(*concat(box((1, 1, 1)), box((1, 1, 1), offset=(1.0, 1.0, 1.0))))
    assert not r.passed
    assert len(r.bodies) == 2
    assert r.offending["nonmanifold_vertices"].tolist() == [7]
    # the shared corner is one vertex: the faces meet only there, which is no intersection
    assert r.overlapping_bodies == () and r.intersecting_pairs == 0
    assert all("1 non-manifold vertex" in b.problems[0] for b in r.bodies)


def test_overlapping_and_nested_bodies():
    r = validate_arrays(*concat(box(), box(offset=(0.5, 0.5, 0.5))))
    assert not r.passed and r.overlapping_bodies == ((0, 1),)
    assert all(b.passed for b in r.bodies)  # each body alone is fine
    assert "intersect or touch" in r.summary()
    r = validate_arrays(*concat(box((4, 4, 4)), box((1, 1, 1))))
    assert not r.passed and r.overlapping_bodies == ()
    assert [b.kind for b in r.bodies] == ["solid", "nested solid"]
    assert "a solid inside body 0" in r.summary()


def test_non_manifold_fin():
    v, f = box()
    v = np.vstack([v, [[0.0, 0.0, 9.0]]])
    fin = [[f[0, 0], f[0, 1], 8]]
    r = validate_arrays(v, np.vstack([f, fin]))
    assert not r.passed
    assert r.bodies[0].nonmanifold_edges == 1 and r.bodies[0].kind == "open"
    assert len(r.offending["nonmanifold_edges"]) == 1


def test_bad_arrays():
    with pytest.raises(InputError, match="shapes"):
        validate_arrays(np.zeros((3, 2)), [[0, 1, 2]])
    assert "no triangles" in validate_arrays(np.zeros((0, 3)), np.zeros((0, 3))).summary()
    assert "do not exist" in validate_arrays(np.zeros((3, 3)), [[0, 1, 5]]).summary()
    v, f = box()
    v[0, 0] = np.nan
    r = validate_arrays(v, f)
    assert not r.passed and "NaN" in r.summary()
    json.dumps(r.as_dict(), allow_nan=False)
    # unreferenced vertices (even NaN ones) are ignored; indices still refer to the input
    v, f = box()
    v = np.vstack([[[np.nan, 0, 0], [7.0, 7, 7]], v])
    r = validate_arrays(v, f[1:] + 2)
    assert r.n_positions == 8 and r.bbox_max == pytest.approx((1, 1.5, 2))
    assert r.bodies[0].volume < 24 and r.bodies[0].open_edges == 3
    assert edge_set(r.offending["open_edges"], v) == edge_set(
        [[f[0, 0] + 2, f[0, 1] + 2], [f[0, 1] + 2, f[0, 2] + 2], [f[0, 2] + 2, f[0, 0] + 2]], v)


# ------------------------------------------------------------------------------------------
# the broken test meshes

#: what each file in tests/data/meshes/broken must be reported for (attribute of body 0 > 0)
BROKEN_EXPECTED = {
    "spot_with_holes.obj": {"open_edges": 84, "holes": 5},
    "pear_five_bodies.ply": {"nonmanifold_edges": 2, "duplicate_faces": 2,
                             "degenerate_faces": 4},
    "polytope_malformed_face.obj": {"degenerate_faces": 2},
    "polytope_internal_faces.obj": {"nonmanifold_edges": 14, "duplicate_faces": 4},
}


@pytest.mark.parametrize("name", sorted(BROKEN_EXPECTED))
def test_shared_broken_files_fail(name):
    r = validate_file(mesh_path(f"broken/{name}"))
    assert not r.passed
    assert r.summary().startswith(f"FAIL {name}: ")
    body = r.bodies[0]
    for attribute, value in BROKEN_EXPECTED[name].items():
        assert getattr(body, attribute) == value, attribute
    json.dumps(r.as_dict(), allow_nan=False)


def test_polytope_internal_faces_intersect():
    """Its internal faces cross the inside of the solid."""
    r = validate_file(mesh_path("broken/polytope_internal_faces.obj"))
    assert r.bodies[0].self_intersections > 0


def test_vase_thin_wall_is_watertight():
    """The vase's defect is its use as a container (a thin wall, rejected by core.meshes), not
    its watertightness: as a print it is a closed solid."""
    r = validate_file(mesh_path("broken/vase_thin_wall_shell.stl"))
    assert r.passed, r.summary()
    assert len(r.bodies) == 1 and r.bodies[0].genus == 0


def test_every_broken_test_mesh_is_covered():
    names = {p.name for p in (MESHES / "broken").iterdir() if p.is_file()}
    assert names <= set(BROKEN_EXPECTED) | {"vase_thin_wall_shell.stl"}


def _exact_segment_meets_triangle(a, b, t) -> bool:
    """Exact rational test (non-coplanar case) that segment ab meets triangle t."""
    from fractions import Fraction

    def q(x):
        return [Fraction(float(c)) for c in x]

    def orient(p0, p1, p2, p3):
        u = [p1[i] - p0[i] for i in range(3)]
        v = [p2[i] - p0[i] for i in range(3)]
        w = [p3[i] - p0[i] for i in range(3)]
        return (u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
                + u[2] * (v[0] * w[1] - v[1] * w[0]))

    a, b, t0, t1, t2 = q(a), q(b), q(t[0]), q(t[1]), q(t[2])
    if orient(t0, t1, t2, a) * orient(t0, t1, t2, b) > 0:
        return False
    s = [orient(a, b, t0, t1), orient(a, b, t1, t2), orient(a, b, t2, t0)]
    return all(x >= 0 for x in s) or all(x <= 0 for x in s)


def test_ycb_peach_scan_has_a_real_fold():
    """The 16k YCB peach scan folds over itself at two spots (faces 12206/15824/15825, about
    1e-7 m deep): found, and confirmed here in exact rational arithmetic."""
    path = mesh_path("fruit/ycb/015_peach.ply")
    r = validate_file(path)
    assert not r.passed and r.bodies[0].closed and r.bodies[0].inconsistent_edges == 0
    pairs = r.offending["intersecting_pairs"].tolist()
    assert sorted(pairs) == [[12206, 15824], [12206, 15825]]
    v, f = read_mesh_arrays(path)
    first, remap = merge_identical(v)
    p, mf = v[first], remap[f]
    for i, j in pairs:
        (shared_vertex,) = set(mf[i]) & set(mf[j])
        far_i = [k for k in mf[i] if k != shared_vertex]
        far_j = [k for k in mf[j] if k != shared_vertex]
        assert _exact_segment_meets_triangle(p[far_i[0]], p[far_i[1]], p[mf[j]]) \
            or _exact_segment_meets_triangle(p[far_j[0]], p[far_j[1]], p[mf[i]])


def test_shared_torus_container_genus_one():
    r = validate_file(mesh_path("containers/torus.obj"))
    assert r.passed and r.bodies[0].genus == 1


# ------------------------------------------------------------------------------------------
# the triangle-triangle test against an independent reference


def _segment_hits_triangle(a, b, t) -> bool:
    e1, e2, d = t[1] - t[0], t[2] - t[0], b - a
    m = np.column_stack([d, -e1, -e2])
    if abs(np.linalg.det(m)) < 1e-12:
        return False
    s, u, w = np.linalg.solve(m, t[0] - a)
    return 0 <= s <= 1 and u >= 0 and w >= 0 and u + w <= 1


def test_triangle_pairs_match_reference():
    """Random non-coplanar pairs: two triangles meet iff an edge of one meets the other."""
    rng = np.random.default_rng(3)
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    shared_faces = np.array([[0, 1, 2], [0, 3, 4]])
    for _ in range(400):
        v = rng.normal(size=(6, 3))
        expected = any(_segment_hits_triangle(v[k], v[(k + 1) % 3], v[3:]) for k in range(3)) \
            or any(_segment_hits_triangle(v[3 + k], v[3 + (k + 1) % 3], v[:3]) for k in range(3))
        assert intersect._pair_meets(v, faces, 0, 1, 1e-9) == expected
        # sharing vertex 0: they meet beyond it iff an opposite edge meets the other triangle
        expected = _segment_hits_triangle(v[1], v[2], v[[0, 3, 4]]) \
            or _segment_hits_triangle(v[3], v[4], v[[0, 1, 2]])
        assert intersect._pair_meets(v, shared_faces, 0, 1, 1e-9) == expected


def test_coplanar_pairs():
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert intersect._pair_meets(np.vstack([tri, tri + [0.2, 0.2, 0]]), faces, 0, 1, 1e-9)
    assert not intersect._pair_meets(np.vstack([tri, tri + [1.2, 0, 0]]), faces, 0, 1, 1e-9)
    # touching at a point counts
    assert intersect._pair_meets(np.vstack([tri, tri + [1.0, 0, 0]]), faces, 0, 1, 1e-9)
    # folded neighbours (shared edge, coplanar, same side) intersect; flat ones do not
    pair = np.array([[0, 1, 2], [1, 0, 3]])
    folded = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, 0.5, 0]])
    assert intersect._pair_meets(folded, pair, 0, 1, 1e-9)
    flat = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.5, -0.5, 0]])
    assert not intersect._pair_meets(flat, pair, 0, 1, 1e-9)


def test_nearly_parallel_apart_triangles_do_not_meet():
    """Planes 1e-9 apart in angle, triangles 0.01-0.09 mm apart (seen on an offset
    surface): the interval test's line is ill-conditioned there and used to say they meet."""
    v = np.array([[22.700779700886542, -41.332627630450745, -8.531535864140466],
                  [21.82622420628799, -40.52488255202738, -8.59834628031566],
                  [22.736372214246757, -40.422479622491984, -8.495943350780266],
                  [21.82622420628799, -40.332627630450745, -8.591644324659313],
                  [22.73988599297077, -40.332627630450745, -8.492429572056253],
                  [22.82622420628799, -40.41237015948412, -8.4858338877724]])
    faces = np.array([[0, 2, 5], [1, 3, 4]])
    assert not intersect._pair_meets(v, faces, 0, 1, 1e-9)
    # a copy of the first triangle turned by 1e-7 rad about an in-plane line through its
    # centroid crosses it along that line: nearly parallel planes that do meet
    t = v[[0, 2, 5]]
    c = t.mean(0)
    u = (t[1] - t[0]) / np.linalg.norm(t[1] - t[0])
    angle = 1e-7
    k = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k
    crossed = np.vstack([t, (t - c) @ rot.T + c])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    assert intersect._pair_meets(crossed, faces, 0, 1, 1e-9)


def test_winding_numbers():
    v, f = box()
    w = intersect.winding_numbers(np.array([[0.0, 0, 0], [5, 0, 0]]), v, f)
    assert w == pytest.approx([1.0, 0.0], abs=1e-9)


# ------------------------------------------------------------------------------------------
# writing and reading back


def _two_bodies() -> list[tuple[np.ndarray, np.ndarray]]:
    s = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    return [(np.array(s.vertices), np.array(s.faces)), box(offset=(5.0, 0.0, 0.0))]


def _volume_and_bodies(vertices: np.ndarray, faces: np.ndarray) -> tuple[float, int]:
    """trimesh's own view: merged vertices, split into connected parts."""
    mesh = trimesh.Trimesh(vertices, faces, process=True)
    return float(mesh.volume), len(mesh.split(only_watertight=False))


@pytest.mark.parametrize("ext", ["stl", "obj", "ply", "3mf"])
def test_round_trip(tmp_path, ext):
    bodies = _two_bodies()
    expected = sum(trimesh.Trimesh(v, f).volume for v, f in bodies)
    path = tmp_path / f"out.{ext}"
    report = write_mesh(path, bodies, names=["ball", "box <1> & co"])
    assert isinstance(report, ValidationReport) and report.passed, report.summary()
    assert report.path == str(path) and len(report.bodies) == 2
    rel = 1e-6 if ext in ("stl", "ply") else 1e-9  # STL and PLY store float32
    assert report.volume == pytest.approx(expected, rel=rel)
    assert sorted(os.listdir(tmp_path)) == [f"out.{ext}"]  # no temporary files left

    v, f = read_mesh_arrays(path)
    assert len(f) == sum(len(f) for _, f in bodies)
    if ext == "3mf":
        # trimesh reads 3MF only with lxml (not a jampacked dependency); meshio cannot
        with zipfile.ZipFile(path) as archive:
            model = archive.read("3D/3dmodel.model").decode()
        assert model.count("<object ") == 2 and 'name="box &lt;1&gt; &amp; co"' in model
        try:
            import lxml  # noqa: F401
            import networkx  # noqa: F401
        except ImportError:
            return
        loaded = trimesh.load(path, force="mesh", process=False)
        volume, count = _volume_and_bodies(loaded.vertices, loaded.faces)
        assert volume == pytest.approx(expected, rel=rel) and count == 2
        return
    loaded = trimesh.load(path, force="mesh", process=False)
    volume, count = _volume_and_bodies(loaded.vertices, loaded.faces)
    assert volume == pytest.approx(expected, rel=rel) and count == 2
    mesh = meshio.read(path)
    tris = np.concatenate([c.data for c in mesh.cells if c.type == "triangle"])
    volume, count = _volume_and_bodies(np.asarray(mesh.points, float), tris)
    assert volume == pytest.approx(expected, rel=rel) and count == 2


def test_single_mesh_call_form(tmp_path):
    v, f = box()
    report = write_mesh(tmp_path / "box.stl", v, f)
    assert report.passed and report.volume == pytest.approx(24.0)
    assert write_mesh(tmp_path / "box.obj", v, f, validate=False) is None


def test_offending_indices_refer_to_the_file_as_read(tmp_path):
    v, f = box()
    path = tmp_path / "hole.stl"
    report = write_mesh(path, v, f[1:], require_valid=False)
    assert not report.passed and path.exists()
    soup, _ = read_mesh_arrays(path)
    assert len(soup) == 3 * 11  # STL: three vertices per face, indices into them
    assert edge_set(report.offending["open_edges"], soup) == edge_set(
        [[f[0, 0], f[0, 1]], [f[0, 1], f[0, 2]], [f[0, 2], f[0, 0]]], v.astype(np.float32))


def test_invalid_mesh_is_not_written(tmp_path):
    v, f = box()
    path = tmp_path / "out.stl"
    path.write_bytes(b"old")
    with pytest.raises(MeshError, match="not watertight") as info:
        write_mesh(path, v, f[:, ::-1])
    assert str(path) in str(info.value) and "inside out" in str(info.value)
    assert path.read_bytes() == b"old"
    assert sorted(os.listdir(tmp_path)) == ["out.stl"]


def test_protected_input_is_never_overwritten(tmp_path, monkeypatch):
    v, f = box()
    source = tmp_path / "input.stl"
    write_mesh(source, v, f)
    before = source.read_bytes()
    monkeypatch.chdir(tmp_path)
    for target in (source, "input.stl", "./sub/../input.stl"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        with pytest.raises(InputError, match="input file"):
            write_mesh(target, v, f, protect=[str(source)])
    link = tmp_path / "link.stl"
    link.symlink_to(source)
    with pytest.raises(InputError, match="input file"):
        write_mesh(link, v, f, protect=[source])
    assert source.read_bytes() == before
    # an output that is not protected is replaced
    out = tmp_path / "out.stl"
    out.write_bytes(b"old")
    assert write_mesh(out, v, f, protect=[source]).passed and out.read_bytes() != b"old"


def test_failed_rename_leaves_old_file_and_no_temp(tmp_path, monkeypatch):
    v, f = box()
    path = tmp_path / "out.obj"
    path.write_bytes(b"old")

    def fail(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", fail)
    with pytest.raises(MeshError, match="No space left"):
        write_mesh(path, v, f)
    assert path.read_bytes() == b"old"
    assert sorted(os.listdir(tmp_path)) == ["out.obj"]


def test_write_errors(tmp_path):
    v, f = box()
    with pytest.raises(InputError, match="unknown mesh format"):
        write_mesh(tmp_path / "out.xyz", v, f)
    with pytest.raises(MeshError, match="does not exist"):
        write_mesh(tmp_path / "missing" / "out.stl", v, f)
    with pytest.raises(InputError, match="one name per body"):
        write_mesh(tmp_path / "out.3mf", [(v, f)], names=["a", "b"])


def test_3mf_components_transforms_and_general_parser(tmp_path):
    """A 3MF as other tools write it: attributes in another order, an object made of
    components, transforms on components and build items."""
    model = """<?xml version="1.0" encoding="UTF-8"?>
<model unit="millimeter" xmlns="http://schemas.microsoft.com/3dmanufacturing/core/2015/02">
 <resources>
  <object id="1" type="model"><mesh>
   <vertices><vertex y="0" x="0" z="0"/><vertex x="1" y="0" z="0"/>
    <vertex x="0" y="1" z="0"/><vertex x="0" y="0" z="1"/></vertices>
   <triangles><triangle v1="0" v2="2" v3="1"/><triangle v1="0" v2="1" v3="3"/>
    <triangle v1="0" v2="3" v3="2"/><triangle v1="1" v2="2" v3="3"/></triangles>
  </mesh></object>
  <object id="2" type="model"><components>
   <component objectid="1" transform="1 0 0 0 1 0 0 0 1 5 0 0"/><component objectid="1"/>
  </components></object>
 </resources>
 <build><item objectid="2" transform="2 0 0 0 2 0 0 0 2 0 0 1"/></build>
</model>"""
    path = tmp_path / "parts.3mf"
    with zipfile.ZipFile(path, "w") as archive:
        _package_parts(archive)
        archive.writestr("3D/3dmodel.model", model)
    v, f = read_mesh_arrays(path)
    assert v[:4].tolist() == [[10, 0, 1], [12, 0, 1], [10, 2, 1], [10, 0, 3]]
    assert v[4:].tolist() == [[0, 0, 1], [2, 0, 1], [0, 2, 1], [0, 0, 3]]
    r = validate_file(path)
    assert r.passed and len(r.bodies) == 2 and r.volume == pytest.approx(2 * 8 / 6)
    # a file written here reads back as written, object by object
    out = tmp_path / "two.3mf"
    bodies = _two_bodies()
    write_mesh(out, bodies)
    v, f = read_mesh_arrays(out)
    n0 = len(bodies[0][0])
    assert np.array_equal(v, np.concatenate([bodies[0][0], bodies[1][0]]))
    assert np.array_equal(f, np.concatenate([bodies[0][1], bodies[1][1] + n0]))


def test_read_errors_name_the_file(tmp_path):
    with pytest.raises(MeshError, match="nothing.stl"):
        read_mesh_arrays(tmp_path / "nothing.stl")
    bad = tmp_path / "bad.3mf"
    bad.write_bytes(b"not a zip")
    with pytest.raises(MeshError, match="bad.3mf"):
        read_mesh_arrays(bad)


def _damaged_3mf_files(tmp_path: Path) -> dict[str, Path]:
    """A valid 3MF, then the ways a 3MF is damaged: a cut zip, compressed data changed, a
    name that is not the UTF-8 it claims, no model part, malformed XML, a vertex without a
    coordinate."""
    good = tmp_path / "good.3mf"
    write_mesh(good, *box())
    data = good.read_bytes()
    out = {}
    out["cut"] = tmp_path / "cut.3mf"
    out["cut"].write_bytes(data[: len(data) // 2])
    with zipfile.ZipFile(good) as archive:
        info = archive.getinfo("3D/3dmodel.model")
    start = info.header_offset + 30 + len(info.filename.encode()) + len(info.extra)
    flipped = bytearray(data)
    for k in range(start + 2, start + 40):
        flipped[k] ^= 0x5A
    out["zlib"] = tmp_path / "zlib.3mf"
    out["zlib"].write_bytes(bytes(flipped))
    # a name in the central directory that claims UTF-8 (flag bit 11) but is not
    # (fuzz seed 4345 case 124: UnicodeDecodeError)
    central = data.rindex(b"PK\x01\x02")
    name = bytearray(data)
    name[central + 9] |= 0x08  # flags' bit 11 (UTF-8 names): bit 3 of the high byte
    name[central + 46] = 0x8B
    out["name"] = tmp_path / "name.3mf"
    out["name"].write_bytes(bytes(name))
    out["no_model"] = tmp_path / "no_model.3mf"
    with zipfile.ZipFile(out["no_model"], "w") as archive:
        archive.writestr("[Content_Types].xml", "<Types/>")
    out["bad_xml"] = tmp_path / "bad_xml.3mf"
    with zipfile.ZipFile(out["bad_xml"], "w") as archive:
        _package_parts(archive)
        archive.writestr("3D/3dmodel.model", "<model><resources><object id='1'>")
    out["no_coordinate"] = tmp_path / "no_coordinate.3mf"
    with zipfile.ZipFile(out["no_coordinate"], "w") as archive:
        _package_parts(archive)
        archive.writestr("3D/3dmodel.model", "<model xmlns='http://schemas.microsoft.com/"
                         "3dmanufacturing/core/2015/02'><resources><object id='1'><mesh>"
                         "<vertices><vertex x='0' y='0'/></vertices><triangles/></mesh>"
                         "</object></resources><build><item objectid='1'/></build></model>")
    return out


def _package_parts(archive: zipfile.ZipFile) -> None:
    """The package parts every 3MF has beside its model (content types, relationships)."""
    from jampacked.core import threemf

    archive.writestr("[Content_Types].xml", threemf.CONTENT_TYPES)
    archive.writestr("_rels/.rels", threemf.RELATIONSHIPS)


def test_damaged_3mf_is_a_clear_error_naming_the_file(tmp_path):
    """Issue 20: a corrupt 3MF raised StopIteration, zlib.error or TypeError."""
    from jampacked.core.meshes import load_mesh

    # each for its own damage, not for parts of the package it lacks
    own = {"bad_xml": "XML of 3D/3dmodel.model is malformed", "no_coordinate": "attribute 'z'"}
    for kind, path in _damaged_3mf_files(tmp_path).items():
        with pytest.raises(MeshError, match=f"{path.name}.*cannot be read as a 3MF") as info:
            read_mesh_arrays(path)
        assert "export it again" in str(info.value), kind
        assert own.get(kind, "") in str(info.value), (kind, str(info.value))
        with pytest.raises(MeshError, match=f"{path.name}.*cannot be read as a 3MF"):
            load_mesh(path)


def test_3mf_is_an_input_format_without_trimesh(tmp_path, monkeypatch):
    """Issue 20: load_mesh read 3MF through trimesh, which needs lxml and networkx; the
    project's own reader reads it (and trimesh is not asked)."""
    from jampacked.core.meshes import load_mesh

    v, f = box()
    path = tmp_path / "box.3mf"
    write_mesh(path, v, f)

    def no_trimesh(*args, **kwargs):
        raise AssertionError("trimesh.load was called for a 3MF file")

    monkeypatch.setattr(trimesh, "load", no_trimesh)
    mesh = load_mesh(path, role="container")
    assert mesh.volume == pytest.approx(24.0)
    assert len(mesh.faces) == 12 and mesh.sha256 is not None


def _obj_text(vertices: np.ndarray, faces: list[str]) -> str:
    return "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist()) + "".join(faces)


def test_obj_with_negative_indices_reads_as_positive(tmp_path):
    """Issue 20: relative (negative) face indices count back from the last vertex defined
    before the face line; an OBJ of two boxes, each written as its vertices then its faces
    with relative indices, validated as non-manifold with duplicate faces."""
    from jampacked.core.meshes import load_mesh

    a, fa = box()
    b, fb = box(offset=(5.0, 0.0, 0.0))
    positive = tmp_path / "positive.obj"
    negative = tmp_path / "negative.obj"
    positive.write_text(_obj_text(np.vstack([a, b]), [])
                        + "".join(f"f {i + 1} {j + 1} {k + 1}\n" for i, j, k in fa)
                        + "".join(f"f {i + 9} {j + 9} {k + 9}\n" for i, j, k in fb))
    # each body: its 8 vertices, then its faces as -8 ... -1 (texture refs too, f v/vt)
    negative.write_text(
        _obj_text(a, []) + "vt 0 0\n"
        + "".join(f"f {i - 8}/-1 {j - 8}/-1 {k - 8}/-1\n" for i, j, k in fa)
        + _obj_text(b, []) + "".join(f"f {i - 8} {j - 8} {k - 8}  # body 2\n"
                                     for i, j, k in fb))
    want = read_mesh_arrays(positive)
    got = read_mesh_arrays(negative)
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    report = validate_file(negative)
    assert report.passed, report.summary()
    assert len(report.bodies) == 2
    one = tmp_path / "one.obj"
    one.write_text(_obj_text(a, []) + "".join(f"f {i - 8} {j - 8} {k - 8}\n" for i, j, k in fa)
                   + "v 100 100 100\n")  # a vertex after the faces: not theirs
    loaded = load_mesh(one)
    reference = tmp_path / "reference.obj"
    reference.write_text(_obj_text(a, []) + "".join(f"f {i + 1} {j + 1} {k + 1}\n"
                                                    for i, j, k in fa))
    expected = load_mesh(reference)
    assert np.array_equal(loaded.vertices, expected.vertices)
    assert np.array_equal(loaded.faces, expected.faces)
    assert loaded.volume == expected.volume == pytest.approx(24.0)


# ------------------------------------------------------------------------------------------
# the command line


@pytest.fixture
def files(tmp_path) -> dict[str, Path]:
    v, f = box()
    good, bad = tmp_path / "good.stl", tmp_path / "bad.obj"
    write_mesh(good, v, f)
    write_mesh(bad, v, f[1:], require_valid=False)
    return {"good": good, "bad": bad, "missing": tmp_path / "missing.stl"}


def test_a_mesh_that_fails_validation_is_not_written_and_the_advice_fits(tmp_path):
    # the advice was written for parts without a clearance (which export now refuses up
    # front) and was given for every mode
    v, f = box()
    with pytest.raises(MeshError, match=r"not watertight.*validate`; if they pass, this is "
                                        r"a defect") as err:
        write_mesh(tmp_path / "open.obj", v, f[1:])
    assert "--clearance" not in str(err.value) and not (tmp_path / "open.obj").exists()


def test_cli_pass_and_fail(files, capsys):
    assert main(["validate", str(files["good"])]) == 0
    out = capsys.readouterr().out
    assert "PASS good.stl: 1 body" in out and "genus" in out
    assert "units³" in out and "mm³" not in out  # an STL carries no unit
    good3mf = files["good"].with_suffix(".3mf")
    write_mesh(good3mf, *box())
    assert main(["validate", str(good3mf)]) == 0
    out = capsys.readouterr().out  # a 3MF's coordinates are read in millimetres
    assert "PASS good.3mf: 1 body, volume 24 mm³" in out and "units" not in out
    assert main(["validate", str(files["good"]), str(files["bad"])]) == 1
    out = capsys.readouterr().out
    assert "PASS good.stl" in out and "FAIL bad.obj: 3 open edges around 1 hole" in out


def test_cli_missing_file(files, capsys):
    assert main(["validate", str(files["bad"]), str(files["missing"])]) == 2
    captured = capsys.readouterr()
    assert "missing.stl" in captured.err and "does not exist" in captured.err
    assert "FAIL bad.obj" in captured.out


def test_cli_json(files, capsys):
    argv = ["validate", "--json", str(files["good"]), str(files["bad"]), str(files["missing"])]
    assert main(argv) == 2
    doc = json.loads(capsys.readouterr().out)
    assert doc["exit_status"] == 2 and doc["passed"] is False
    good, bad, missing = doc["files"]
    assert good["passed"] and good["n_bodies"] == 1 and good["bodies"][0]["genus"] == 0
    assert good["volume"] == pytest.approx(24.0)
    assert not bad["passed"] and bad["bodies"][0]["open_edges"] == 3
    assert len(bad["offending"]["open_edges"]) == 3 and bad["offending_counts"]["open_edges"] == 3
    assert missing["passed"] is False and "does not exist" in missing["error"]


def test_cli_can_skip_the_manifold3d_cross_check(files, capsys):
    """--no-manifold3d skips only manifold3d's status (said in the report); the own checks
    still find the open edges."""
    assert main(["validate", "--json", "--no-manifold3d", str(files["good"]),
                 str(files["bad"])]) == 1
    good, bad = json.loads(capsys.readouterr().out)["files"]
    assert good["passed"] and good["manifold_status"] == "skipped"
    assert not bad["passed"] and bad["bodies"][0]["open_edges"] == 3
    assert main(["validate", "--json", str(files["good"])]) == 0
    assert json.loads(capsys.readouterr().out)["files"][0]["manifold_status"] == "NoError"


def test_cli_help(capsys):
    assert main(["--help"]) == 0
    assert "validate" in capsys.readouterr().out
    assert main(["validate", "--help"]) == 0
    text = capsys.readouterr().out
    assert "--json" in text and "Exit status" in text and "self-intersections" in text
    assert main(["validate"]) == 2  # FILE is required


def test_unwelded_faces_are_named_not_counted_as_thousands_of_bodies(tmp_path):
    """validate of a mesh whose corners were rounded apart reported one body and one hole
    per triangle; `pack` named it. Now validate says what it is, first, and the fix."""
    s = trimesh.creation.icosphere(subdivisions=2, radius=10.0)
    corners = np.asarray(s.vertices)[np.asarray(s.faces)].reshape(-1, 3)
    corners = corners + np.random.default_rng(3).normal(scale=1e-6, size=corners.shape)
    r = validate_arrays(corners, np.arange(len(corners)).reshape(-1, 3))
    assert not r.passed
    assert r.problems[0].startswith("its faces are not joined")
    assert "merge the vertices by distance" in r.summary()
    holed = validate_arrays(np.asarray(s.vertices), np.asarray(s.faces)[1:])
    assert not any("not joined" in p for p in holed.failures())
