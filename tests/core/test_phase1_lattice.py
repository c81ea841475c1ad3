"""Phase 1's lattice: the paper's cubic one, or face-centred cubic where the cubic one holds
many objects (docs/notes-core.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree
from testdata import mesh_path

from jampacked.core import phases
from jampacked.core.api import pack
from jampacked.core.container import build_container, deepest_points, interior_points
from jampacked.core.errors import InputError
from jampacked.core.kernels import sample_grid_many
from jampacked.core.meshes import box_mesh
from jampacked.core.options import PackOptions, PhaseOptions

FRUIT = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]


def _box():
    m = box_mesh([30.0, 20.0, 40.0])
    return build_container(m.vertices, m.faces, m.volume, 1.0)


@pytest.mark.parametrize("seed", [1, 2])
def test_fcc_points_are_a_face_centred_lattice_of_the_same_point_density(seed):
    c, spacing, depth = _box(), 1.0, 2.0
    fcc = interior_points(c, spacing, depth, np.random.default_rng(seed), lattice="fcc")
    cubic = interior_points(c, spacing, depth, np.random.default_rng(seed))
    # about as many points as the cubic lattice (up to a row of cells at each face, which
    # the random offset decides); the cell below fixes the density exactly
    inside = (30.0 - 2 * depth) * (20.0 - 2 * depth) * (40.0 - 2 * depth)
    assert len(fcc) == pytest.approx(inside / spacing ** 3, rel=0.15)
    assert len(fcc) == pytest.approx(len(cubic), rel=0.15)
    g = c.grid
    assert sample_grid_many(g.values, g.origin, g.spacing, fcc).min() >= depth
    # each point away from the lattice's edge has its 12 nearest at a / sqrt(2) and the
    # next at a, a the cell's side: 4 points per a^3 = spacing^3 (none nearer: the four
    # sublattices never coincide)
    a = spacing * 4.0 ** (1.0 / 3.0)
    d, _ = cKDTree(fcc).query(fcc, k=14)
    assert d[:, 1].min() == pytest.approx(a / math.sqrt(2.0), rel=1e-9)
    lo, hi = fcc.min(axis=0) + a, fcc.max(axis=0) - a
    deep = np.all((fcc > lo) & (fcc < hi), axis=1)
    assert deep.sum() > 100
    np.testing.assert_allclose(d[deep, 1:13], a / math.sqrt(2.0), rtol=1e-9)
    assert d[deep, 13].min() == pytest.approx(a, rel=1e-9)


def test_an_unknown_lattice_is_refused():
    with pytest.raises(ValueError, match="unknown lattice 'hex'"):
        interior_points(_box(), 1.0, 1.0, lattice="hex")
    with pytest.raises(InputError, match="phase1_lattice must be 'cubic', 'fcc' or None"):
        PhaseOptions(phase1_lattice="hex")
    with pytest.raises(InputError, match="phase1_lattice"):
        PackOptions.from_flat({"phase1_lattice": "hex"})


def test_the_lattice_follows_the_cubic_lattice_size_unless_given():
    many = phases.MANY_OBJECTS
    assert phases.phase1_lattice(None, many) == "cubic"
    assert phases.phase1_lattice(None, many + 1) == phases.MANY_OBJECTS_LATTICE == "fcc"
    assert phases.phase1_lattice("cubic", many + 1) == "cubic"
    assert phases.phase1_lattice("fcc", 5) == "fcc"


def test_the_fcc_density_follows_the_cubic_lattice_size_unless_given():
    assert phases.phase1_fcc_density(None, 15_000) == phases.FCC_DENSITY == 0.55
    assert phases.phase1_fcc_density(None, 15_001) == 0.58
    assert phases.phase1_fcc_density(None, 50_000) == 0.58
    assert phases.phase1_fcc_density(None, 50_001) == 0.6
    assert phases.phase1_fcc_density(0.5, 50_001) == 0.5
    for bad in (0.0, 1.0, -0.2, "0.6", True):
        with pytest.raises(InputError, match="phase1_fcc_density must be a fraction"):
            PhaseOptions(phase1_fcc_density=bad)
    with pytest.raises(InputError, match="phase1_fcc_density"):
        PackOptions.from_flat({"phase1_fcc_density": 1.5})


def test_deepest_points_keep_the_deepest_in_their_order():
    c = _box()  # 30 x 20 x 40 about the origin: depth 10 - |y| away from the other walls
    pts = np.array([[0.0, y, 0.0] for y in (9.5, 0.0, -8.0, 3.0, 9.9, -3.0)])
    np.testing.assert_array_equal(deepest_points(c, pts, 6), pts)
    np.testing.assert_array_equal(deepest_points(c, pts, 9), pts)
    # depths 0.5, 10, 2, 7, 0.1, 7: the four deepest, in the given order (a tie: both)
    np.testing.assert_array_equal(deepest_points(c, pts, 4), pts[[1, 2, 3, 5]])
    np.testing.assert_array_equal(deepest_points(c, pts, 1), pts[[1]])
    assert deepest_points(c, pts, 0).shape == (0, 3)


def _phase1(monkeypatch, seed: int = 1, **flat):
    """Phase 1 of a small box of fruit; returns its stats and the lattices it asked for
    as (spacing, lattice, points, min_depth)."""
    calls = []

    def spy(container, spacing, min_depth, rng=None, lattice="cubic"):
        pts = interior_points(container, spacing, min_depth, rng, lattice)
        calls.append((spacing, lattice, len(pts), min_depth))
        return pts

    monkeypatch.setattr(phases, "interior_points", spy)
    options = PackOptions.from_flat({"extra_passes": [], "max_attempts": 1, **flat})
    p = pack("box:40x40x40", FRUIT, seed=seed, type_scale=100.0, fidelity="low",
             options=options)
    return p.report.phase1, calls  # phase 1's first, then phase 2's


#: coarse growth for the runs whose lattice alone is checked, not how it grows (the cubic
#: one grew 30 steps, 14 s): the lattice is chosen and placed before any object grows
COARSE = {"phase1_growth_steps": 6, "phase1_iterations": 10}


def test_phase1_on_many_objects_grows_an_fcc_lattice_at_its_own_density(monkeypatch):
    cubic, calls = _phase1(monkeypatch, **COARSE)
    assert cubic.extra["lattice"] == "cubic"
    (spacing, lattice, n, _), = calls[:1]
    assert lattice == "cubic" and cubic.inserted == n
    # the same scene as if its lattice held many objects: the cubic lattice is counted,
    # then phase 1 grows the fcc lattice of phase1_fcc_density (0.55 against 0.5)
    monkeypatch.setattr(phases, "MANY_OBJECTS", 5)
    fcc, calls = _phase1(monkeypatch)
    assert fcc.extra["lattice"] == "fcc"
    assert [c[:2] for c in calls[:2]] == [(spacing, "cubic"),
                                          (pytest.approx(spacing * (0.5 / 0.55) ** (1 / 3)),
                                           "fcc")]
    assert fcc.inserted == calls[1][2] and fcc.grown >= 0.9 * fcc.inserted
    assert fcc.extra["fcc_density"] == 0.55
    # with a cubic lattice of more objects than a DENSER_FCC count, its denser lattice
    monkeypatch.setattr(phases, "DENSER_FCC", ((5, 0.58),))
    denser, calls = _phase1(monkeypatch, **COARSE)
    assert denser.extra["fcc_density"] == 0.58
    assert calls[1][:2] == (pytest.approx(spacing * (0.5 / 0.58) ** (1 / 3)), "fcc")
    assert denser.inserted == calls[1][2] > fcc.inserted
    assert calls[1][3] == calls[0][3]  # points as near the wall as the cubic lattice's
    # asked for explicitly, whatever the size
    monkeypatch.setattr(phases, "MANY_OBJECTS", 10_000)
    forced, calls = _phase1(monkeypatch, phase1_lattice="fcc", phase1_fcc_density=0.6,
                            **COARSE)
    assert forced.extra["lattice"] == "fcc" and forced.inserted == calls[1][2] > 0
    assert calls[1][0] == pytest.approx(spacing * (0.5 / 0.6) ** (1 / 3))
    # from DENSE_FCC, points half the fruit's mean equivalent radius deep at least
    mean_radius = (3 * 0.5 * spacing ** 3 / (4 * math.pi)) ** (1 / 3)
    assert phases.DENSE_FCC == 0.6
    assert calls[1][3] == pytest.approx(phases.DENSE_FCC_DEPTH * mean_radius)
    assert calls[0][3] < calls[1][3]


def test_phase1_grows_no_more_fcc_objects_than_its_density_asks(monkeypatch):
    # seed 2's offset puts layers of the lattice just inside the box's walls: 256 points
    # where 64,000 mm^3 at 0.55 of the fruit's mean volume asks for 235; the shallowest
    # are dropped. Seed 1's 196 points are all kept.
    monkeypatch.setattr(phases, "MANY_OBJECTS", 5)
    under, under_calls = _phase1(monkeypatch, seed=1)  # its cubic lattice gives the spacing
    spacing = under_calls[0][0]
    cap = int(40.0 ** 3 / (spacing ** 3 * 0.5 / 0.55))
    over, calls = _phase1(monkeypatch, seed=2)
    assert calls[1][2] > cap and over.inserted == cap
    assert over.extra["fcc_dropped"] == calls[1][2] - cap
    assert over.grown >= 0.9 * over.inserted
    assert under.inserted == under_calls[1][2] < cap and under.extra["fcc_dropped"] == 0
