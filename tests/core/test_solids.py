"""manifold3d solids from the project's arrays (`core/solids.py`)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from jampacked.core.solids import outside_of, to_solid


@pytest.mark.parametrize("double", [True, False])
def test_read_only_arrays_make_solids(double):
    # load_mesh freezes its arrays, and manifold3d refused them (a TypeError) when they
    # already had the dtype asked for, so no copy was made
    box = trimesh.creation.box(extents=(2.0, 3.0, 4.0))
    v = np.array(box.vertices, np.float64 if double else np.float32)
    f = np.array(box.faces, np.uint64 if double else np.uint32)
    v.flags.writeable = False
    f.flags.writeable = False
    solid = to_solid(v, f, double=double)
    assert solid.volume() == pytest.approx(24.0)
    assert not v.flags.writeable  # the caller's arrays are left as they were
    if double:
        gap = solid.min_gap(outside_of(v, np.asarray(f, np.int64)), 1.0)
        assert gap == pytest.approx(0.0, abs=1e-9)
