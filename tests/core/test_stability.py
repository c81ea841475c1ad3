"""How pack() ends where methods fail (the stability map's cases, small and fast).

Each case must end in a certified packing or a clear JampackedError: never NaN, an object
outside the container, a hang or a crash. Checks here are independent of the engine's own:
centres by the generalised winding number of the container mesh, volume outside by
manifold3d on the placed mesh files. bench/stability.py runs the same cases at full size.
"""

from __future__ import annotations

import json
import re
import sys

import manifold3d as m3
import numpy as np
import pytest
import trimesh
from testdata import MESHES, REPO, cavity_passes, mesh_path

from jampacked.core.api import pack
from jampacked.core.errors import PackingError
from jampacked.core.meshes import load_mesh, mesh_from_arrays
from jampacked.core.metrics import best_tvd
from jampacked.core.options import CavityPassOptions, PackOptions
from jampacked.core.repair import MIX_SLACK

FRUIT = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in
         ("011_banana", "012_strawberry", "014_lemon", "015_peach", "017_orange")]
BANANA, STRAWBERRY, LEMON, PEACH, ORANGE = FRUIT


def _winding_inside(vertices: np.ndarray, faces: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) bool: inside a closed mesh by the generalised winding number."""
    tri = np.asarray(vertices, float)[np.asarray(faces)]
    r = tri[None] - np.asarray(points, float).reshape(-1, 1, 1, 3)  # (N,F,3,3)
    a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("nfi,nfi->nf", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("nfi,nfi->nf", a, b) * lc
           + np.einsum("nfi,nfi->nf", b, c) * la + np.einsum("nfi,nfi->nf", c, a) * lb)
    return np.abs(np.arctan2(det, den).sum(axis=1) / (2 * np.pi)) > 0.5


def _container(p, spec_or_path: str) -> trimesh.Trimesh:
    """The container in the packing's frame, rebuilt from the spec or file."""
    if spec_or_path.startswith("box:"):
        ext = [float(x) for x in spec_or_path[4:].split("x")]
        m = trimesh.creation.box(extents=ext)
    else:
        m = trimesh.load(spec_or_path, force="mesh", process=True)
    f = p.frame_from_file
    return trimesh.Trimesh(m.vertices @ f[:3, :3].T + f[:3, 3], m.faces, process=False)


def _assert_sane(p, container: str, *, min_objects: int = 1, exact_outside: bool = False):
    """Certified, every number finite, unit rotations, full scale, centres inside the
    container; with exact_outside, each placed mesh's volume outside (manifold3d) too."""
    cert = p.certificate
    assert cert["certified"], cert
    assert cert["worst_overlap"] <= 1e-4 and cert["worst_outside"] <= 1e-4, cert
    assert p.n >= min_objects, p.n
    for arr in (p.translations, p.rotations, p.scales):
        assert np.all(np.isfinite(arr))
    numbers = [p.metrics["density"], p.metrics["tvd"]] + [
        cert[k] for k in ("worst_overlap", "worst_outside", "min_pair_gap", "min_wall_gap")
        if cert[k] is not None]
    if p.metrics.get("nni_mean") is not None:
        numbers.append(p.metrics["nni_mean"])
    assert np.all(np.isfinite(numbers)), numbers
    assert np.allclose(np.linalg.norm(p.rotations, axis=1), 1.0)
    assert np.allclose(p.scales, 1.0)
    cm = _container(p, container)
    inside = _winding_inside(cm.vertices, cm.faces, p.translations)
    assert inside.all(), np.flatnonzero(~inside)
    if exact_outside:
        lo, hi = cm.bounds
        box = m3.Manifold.cube((hi - lo + 20).tolist(), True).translate(((lo + hi) / 2).tolist())
        outside = box - m3.Manifold(m3.Mesh(vert_properties=cm.vertices.astype(np.float32),
                                            tri_verts=cm.faces.astype(np.uint32)))
        mats = p.matrices()
        for k in range(p.n):
            t = p.types[p.type_index[k]]
            m = mats[k] @ t.local_from_file
            mesh = load_mesh(t.path)
            v = mesh.vertices @ m[:3, :3].T + m[:3, 3]
            solid = m3.Manifold(m3.Mesh(vert_properties=v.astype(np.float32),
                                        tri_verts=mesh.faces.astype(np.uint32)))
            assert (solid ^ outside).volume() <= 1e-4 * t.volume * 1.01, k


# --- clear errors -------------------------------------------------------------------------


def test_objects_larger_than_the_container_raise_packing_error():
    """Lemons and oranges (x300: 17-22 mm across) in a 6 mm box: refused up front, with the
    sizes and the fix in the message."""
    with pytest.raises(PackingError, match="no object fits") as e:
        pack("box:6x6x6", [LEMON, ORANGE], type_scale=300.0, fidelity="low", time_budget=2.0)
    msg = str(e.value)
    assert "014_lemon" in msg and "equivalent radius 8.537" in msg and "--type-scale" in msg, msg


def test_clearance_too_large_is_a_clear_error():
    """A 40 mm box is 20 mm deep: a 20 mm clearance leaves no room for any lemon."""
    with pytest.raises(PackingError, match="plus the clearance 20"):
        pack("box:40x40x40", [LEMON], type_scale=300.0, clearance=20.0, fidelity="low",
             time_budget=2.0)


@pytest.mark.parametrize("container,kwargs", [
    ("box:80x80x80", {"clearance": 32.0}),  # depth 40 > 4.3 + 32, yet no lemon fits
    (str(mesh_path("containers/spot.obj")), {"container_size": 30.0}),
])
def test_nothing_fits_past_the_up_front_check_is_a_clear_error(container, kwargs):
    """The first check (depth against half the smallest equivalent radius) passes here; the
    per-type check (largest inner sphere plus clearance against the depth) must catch it
    (stability map: clearance-32, too-large-all). No time budget: under load a budget
    could end placement before its first try, and the run then ends empty, not in error."""
    with pytest.raises(PackingError, match="cannot fit|no object could be placed"):
        pack(container, [LEMON, ORANGE] if "box" in container else FRUIT, type_scale=300.0,
             fidelity="low", **kwargs)


# --- certified packings where methods struggle ----------------------------------------------


def test_one_type_that_fits_nowhere_is_named():
    """A 16 mm slab holds strawberries (about 10 mm thick) but no orange (about 21 mm):
    instead of a packing with the orange silently missing, the error names the orange
    (stability map: too-large-one)."""
    with pytest.raises(PackingError, match=r"017_orange \(.*017_orange\.obj\) cannot fit") as e:
        pack("box:16x80x80", [STRAWBERRY, ORANGE], type_scale=300.0, fidelity="low",
             time_budget=2.0)
    assert "012_strawberry" not in str(e.value)


def test_extreme_shares_99_to_1_keep_the_mix():
    box = "box:50x50x50"
    p = pack(box, [LEMON, ORANGE], [0.99, 0.01], type_scale=300.0, seed=2, fidelity="low",
             time_budget=3.0)
    _assert_sane(p, box, min_objects=10)
    counts = np.bincount(p.type_index, minlength=2)
    assert counts[0] >= 10 * max(counts[1], 1), counts
    # phase 1 keeps the mix; the paper's phase 2 inserts the largest type that fits, so the
    # 1% type gains a little there
    assert p.metrics["tvd"] <= 0.1, p.metrics["tvd"]


@pytest.mark.parametrize("shares", [[1.0, 0.0], [0.0, 1.0]])
def test_a_zero_share_type_is_never_placed(shares):
    """100/0: phase 1's fallback and the paper's phase 2 (largest type that fits) placed one
    object of the 0% type before; now the mix is exact."""
    box = "box:60x60x60"
    p = pack(box, [LEMON, ORANGE], shares, type_scale=300.0, seed=1, fidelity="low",
             time_budget=3.0)
    _assert_sane(p, box, min_objects=8)
    assert set(p.type_index.tolist()) == {int(np.argmax(shares))}
    assert p.metrics["tvd"] == 0.0


def test_one_type_fills_the_box():
    box = "box:50x50x50"
    p = pack(box, [ORANGE], type_scale=300.0, seed=2, fidelity="low", time_budget=3.0)
    _assert_sane(p, box, min_objects=6)
    assert set(p.type_index.tolist()) == {0}
    assert p.metrics["tvd"] == 0.0
    assert p.metrics["density"] > 0.25, p.metrics["density"]


def _scaled_strawberry(ratio: float):
    """The strawberry scaled so that the orange's equivalent radius is `ratio` times its."""
    straw = load_mesh(STRAWBERRY)
    k = (202.0e-6 / 48.0e-6) ** (1 / 3) / ratio  # f(orange) / f(strawberry) / ratio
    return mesh_from_arrays(straw.vertices * k, straw.faces, name=f"strawberry/{ratio:g}")


def _mix_bound(shares: np.ndarray, n: int,
               tolerance: float = CavityPassOptions().max_tvd) -> float:
    """The TVD a packing of n objects may have: the tolerance, or with few objects one
    object from the best mix n allows (`metrics.mix_cap`)."""
    return max(tolerance, best_tvd(shares, n) + 1.0 / n)


def test_size_ratio_1_to_5_keeps_the_mix_through_the_cavity_fill():
    """Equal shares of an orange (22 mm) and a strawberry a fifth of its size: the holes
    between oranges fit only strawberries, and the paper's cavity fill (phase 2) put one in
    each (TVD 0.28 in the stability map: 49 oranges, 174 strawberries). No insertion may
    take the mix beyond the tolerance: phase 2 ends within it, and so does the packing."""
    box = "box:50x50x50"
    p = pack(box, [ORANGE, _scaled_strawberry(5.0)], type_scale=300.0, seed=1,
             fidelity="low", options=PackOptions(cavity=CavityPassOptions(factors=())))
    _assert_sane(p, box, min_objects=6)
    shares = np.array([0.5, 0.5])
    one, two = p.metrics["after_phase1"], p.metrics["after_phase2"]
    assert two["count"] > one["count"]  # phase 2 filled holes: the check bites
    assert two["tvd"] <= _mix_bound(shares, two["count"]) + 1e-9, two
    assert p.metrics["tvd"] <= _mix_bound(shares, p.n) + MIX_SLACK, p.metrics


def test_a_zero_mix_tolerance_keeps_the_best_mix_the_count_allows():
    """The hand at 150 mm holds 17 of the lemon, strawberry and banana x300. With the
    default tolerance the extra passes took one object beyond the best mix (TVD 0.098
    against 0.039 for 17); --mix-tolerance 0 asks for the mix as close as the count allows,
    and gets it, with fewer objects."""
    hand = str(mesh_path("containers/hand.obj"))
    kw = {"seed": 1, "container_size": 150.0, "type_scale": 300.0, "attempts": 1}
    q = np.full(3, 1 / 3)
    # the passes at factor 0.4 add nothing here either way: three factors show it
    factors = (0.8, 0.6, 0.5)
    loose = pack(hand, [LEMON, STRAWBERRY, BANANA], **kw,
                 options=cavity_passes(*factors))
    assert loose.metrics["tvd"] > best_tvd(q, loose.n) + 0.03  # the case bites
    strict = pack(hand, [LEMON, STRAWBERRY, BANANA], **kw,
                  options=PackOptions(cavity=CavityPassOptions(factors=factors, max_tvd=0.0)))
    assert strict.certificate["certified"] and strict.n > 10
    assert strict.metrics["tvd"] == pytest.approx(best_tvd(q, strict.n), abs=1e-9)


def test_size_ratio_1_to_20_is_certified_with_both_types():
    """An orange (22 mm) and a strawberry scaled to a twentieth of its equivalent radius:
    the container grid is capped (220 cells across; a flat box keeps it small), the small
    type still gets placed and certified, and the mix stays within the tolerance (the
    cavity fill once filled every hole with the small type)."""
    small = _scaled_strawberry(20.0)
    box = "box:48x26x26"
    p = pack(box, [ORANGE, small], type_scale=300.0, seed=1, fidelity="low",
             time_budget=2.0)
    _assert_sane(p, box, min_objects=6)
    counts = np.bincount(p.type_index, minlength=2)
    assert counts.min() >= 2, counts
    assert p.metrics["tvd"] <= _mix_bound(np.array([0.5, 0.5]), p.n) + MIX_SLACK, p.metrics
    v = [t.volume for t in p.types]
    assert 7000 < v[0] / v[1] < 9000  # 20^3 = 8000 by equivalent radius


def test_elongated_banana_alone_is_certified():
    box = "box:60x60x60"
    p = pack(box, [BANANA], type_scale=300.0, seed=1, fidelity="low", time_budget=3.0)
    _assert_sane(p, box, min_objects=4, exact_outside=True)


def test_thin_features_hand_is_certified_nothing_outside():
    """A 150 mm hand: fruit (13-22 mm) fit the palm, not the fingers; every placed mesh is
    inside the hand (exact volume outside, manifold3d) and every centre too."""
    hand = str(mesh_path("containers/hand.obj"))
    p = pack(hand, FRUIT, container_size=150.0, type_scale=300.0, seed=1, fidelity="low",
             time_budget=4.0)
    _assert_sane(p, hand, min_objects=5, exact_outside=True)
    assert 0.1 < p.metrics["density"] < 0.6


@pytest.mark.serial
def test_tiny_budget_with_thousands_expected_ends_certified_with_what_it_placed():
    """About 26000 strawberries (x45, 2 mm) start in phase 1's lattice of a 60 mm box; with
    a 1 s budget the run stops on the deadline with most of them ungrown (phase 1 grew
    about 6500 of them here), certifies what it placed and says it stopped. Nothing runs
    after the deadline but certification: phase 2's candidate search (points x objects, half
    a second here) is skipped."""
    box = "box:60x60x60"
    p = pack(box, [STRAWBERRY], type_scale=45.0, seed=1, fidelity="low", time_budget=1.0)
    assert p.report.stopped == "deadline"
    assert p.report.phase1.inserted > 20000
    _assert_sane(p, box, min_objects=20)
    assert p.n < p.report.phase1.inserted
    assert p.report.phase2.stopped == "deadline"
    assert p.report.phase2.seconds < 0.2, p.report.phase2
    assert p.timings["total"] < 60.0, p.timings


@pytest.mark.serial
def test_tens_of_thousands_of_lattice_objects_keep_the_budget():
    """46000 strawberries (x20) start in phase 1's lattice of a flat box: settling them used to
    cost (objects x objects), 4.5 s past a 1 s budget with nothing placed; only objects near
    the wall start the settling now, and placement stops on time."""
    box = "box:60x60x10"
    p = pack(box, [STRAWBERRY], type_scale=20.0, seed=1, fidelity="low", time_budget=1.0)
    assert p.report.phase1.inserted > 40000
    assert p.report.stopped == "deadline"
    assert p.report.phase1.seconds < 2.0, p.report.phase1
    assert p.certificate["certified"] and np.all(np.isfinite(p.translations))


# --- the stability bench's own runner: a hang and a crash are recorded, not fatal -----------


@pytest.fixture(scope="module")
def stability():
    sys.path.insert(0, str(REPO / "bench"))
    try:
        import stability
    finally:
        sys.path.remove(str(REPO / "bench"))
    return stability


def _fake_case(stability, container: str) -> dict:
    return stability._case("fake", "runner", "none", 0, container, [LEMON], 1.0, timeout=3.0)


def test_bench_records_a_hang(stability):
    rec = stability.run_in_child(_fake_case(stability, "__hang__"), MESHES)
    assert rec["outcome"] == "hang"
    assert 3.0 <= rec["wall_seconds"] < 30.0
    assert stability.problems(rec) == ["expected certified, got hang"]


def test_bench_records_a_crash_with_its_stderr(stability):
    rec = stability.run_in_child(_fake_case(stability, "__crash__"), MESHES, timeout=120.0)
    assert rec["outcome"] == "crash" and rec["exit_code"] != 0
    assert "deliberate crash" in rec["stderr_tail"]
    json.dumps(rec)  # what the bench writes


@pytest.mark.parametrize("container,shape,count", [
    ("box:4.2x4.2x4.2", "ball", 1),  # 0.1 to spare around a radius-2 ball
    ("box:9.5x9.5x9.5", "cube", 1),  # 0.25 around a 9 mm cube, which must sit square
    ("box:9.5x9.5x40", "cube", 4),
])
def test_an_object_that_only_just_fits_is_placed(tmp_path, container, shape, count):
    # the container grid read the middle of the box up to half a cell shallower than it is,
    # so with less room to spare than that no object fitted ("no object could be placed")
    mesh = (trimesh.creation.icosphere(subdivisions=3, radius=2.0) if shape == "ball"
            else trimesh.creation.box([9.0, 9.0, 9.0]))
    path = tmp_path / f"{shape}.stl"
    mesh.export(path)
    p = pack(container, [str(path)], seed=1)
    assert p.n == count
    assert p.certificate["certified"]
    if container == "box:4.2x4.2x4.2":
        # a refined container grid is what the report says: it kept the fidelity's 6 cells
        # per radius after the grid was refined (this packing was packed again for it alone)
        detail = p.report.fidelity_detail
        f_min = (3 * p.types[0].volume / (4 * np.pi)) ** (1 / 3)
        assert detail.container_cells == pytest.approx(f_min / p.report.container_grid_spacing)
        assert detail.container_cells > 30
        assert any("only just fits" in r for r in detail.reasons)


def test_no_object_placed_names_the_depth_a_type_needs(tmp_path, monkeypatch):
    # the message compared the depth with the equivalent radius (5.58 for a 9 mm cube,
    # deeper than a 9.5 mm box) and only advised rescaling
    import jampacked.core.phases as phases
    import jampacked.core.placement as placement

    path = tmp_path / "cube.stl"
    trimesh.creation.box([9.0, 9.0, 9.0]).export(path)
    monkeypatch.setattr(phases, "grow", lambda *args, **kwargs: False)
    # the cubes would start stacked at full size, or in a grid, never grown
    # (`core/stacking.py`, `core/box_grid.py`)
    monkeypatch.setattr(placement, "stack_start", lambda *args, **kwargs: None)
    monkeypatch.setattr(placement, "box_grid", lambda *args, **kwargs: None)
    with pytest.raises(PackingError, match=r"cube, the type needing the least depth, needs "
                       r"at least 4\.5 \(its inner room\).*--fidelity high"):
        pack("box:9.5x9.5x40", [str(path)], seed=1)
    # high fidelity already: no advice to ask for it
    with pytest.raises(PackingError) as err:
        pack("box:9.5x9.5x40", [str(path)], seed=1, fidelity="high")
    assert "no object fitted anywhere" in str(err.value) and "fidelity" not in str(err.value)
    monkeypatch.undo()
    # shallower than the cube needs, within a grid cell: the check up front settles it on
    # the container mesh (`room.has_depth`; the run used to place nothing first)
    with pytest.raises(PackingError) as err:
        pack("box:8.9x8.9x8.9", [str(path)], seed=1)
    assert "cube (" in str(err.value) and "cannot fit" in str(err.value)
    assert "deepest interior point is about 4.4" in str(err.value)
    assert "needs at least 4.5 (the inscribed radius)" in str(err.value)
    assert "fidelity" not in str(err.value)


@pytest.mark.parametrize("side,clearance", [(9.03, 0.0), (9.25, 0.1)])
def test_no_object_placed_says_what_the_approximation_keeps_and_the_size_that_fits(
        tmp_path, monkeypatch, side, clearance):
    # the depth was enough for the cube's inner room plus the clearance, and the message
    # said only "no object fitted anywhere" and advised --fidelity high, which failed too:
    # the contact margins and the grid's half cell at the depth's peak took the rest
    import jampacked.core.placement as placement

    path = tmp_path / "cube.stl"
    trimesh.creation.box([9.0, 9.0, 9.0]).export(path)
    # a box of one type now takes the grid of its boxes (`core/box_grid.py`), which needs no
    # margin: the cube is placed, where a container of another shape ends in the message
    grid = pack(f"box:{side}x{side}x{side}", [str(path)], seed=1, clearance=clearance)
    assert grid.n == 1 and grid.certificate["certified"] and grid.report.phase1.extra["grid"]
    monkeypatch.setattr(placement, "box_grid", lambda *args, **kwargs: None)
    with pytest.raises(PackingError) as err:
        pack(f"box:{side}x{side}x{side}", [str(path)], seed=1, clearance=clearance)
    msg = str(err.value)
    assert "contact margins" in msg and "half a container grid cell" in msg, msg
    assert "so none fits the approximation" in msg and "fidelity" not in msg, msg
    size = float(re.search(r"--container-size ([0-9.]+) ", msg).group(1))
    assert side < size < side * 1.01
    p = pack(f"box:{size}x{size}x{size}", [str(path)], seed=1, clearance=clearance)
    assert p.n == 1 and p.certificate["certified"]
    # a capped container grid is what the report says: a 9 mm cube in a 9.05 box asked for
    # 670 cells per radius, the grid's cap per axis allows 136, and the report said 670
    # (that box was packed for this alone; this one is capped too, as the reason says)
    detail = p.report.fidelity_detail
    f_min = (3 * p.types[0].volume / (4 * np.pi)) ** (1 / 3)
    assert detail.container_cells == pytest.approx(f_min / p.report.container_grid_spacing)
    assert any("the most the container's size allows" in r for r in detail.reasons)
