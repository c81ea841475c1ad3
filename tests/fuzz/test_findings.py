"""Faults the fuzz harness found (bench/fuzz_inputs.py), each as a fast test of its own."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from jampacked.cli.main import main
from jampacked.core.errors import MeshError
from jampacked.core.meshes import load_mesh
from jampacked.export.validate import validate_file


def _binary_ply(path, vertices, faces) -> None:
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(vertices)}\nproperty double x\nproperty double y\n"
            f"property double z\nelement face {len(faces)}\n"
            "property list uchar int vertex_indices\nend_header\n").encode()
    rec = np.zeros(len(faces), dtype=[("c", "u1"), ("i", "<i4", 3)])
    rec["c"] = 3
    rec["i"] = faces
    path.write_bytes(head + np.asarray(vertices, "<f8").tobytes() + rec.tobytes())


@pytest.fixture
def huge_ply(tmp_path):
    """A sphere at 1e300 (seed 2 case 286, seed 4 cases 224, 245, 295)."""
    ball = trimesh.creation.icosphere(1, radius=4.0)
    path = tmp_path / "huge.ply"
    _binary_ply(path, ball.vertices * 1e300, ball.faces)
    return path


def test_loading_a_mesh_whose_coordinates_overflow_is_refused_by_name(huge_ply):
    # was: scipy's "Encountering floating point overflow" from merging vertices
    with pytest.raises(MeshError, match=r"huge\.ply.*coordinates as large as 4e\+300"):
        load_mesh(huge_ply)


def test_validating_a_mesh_whose_coordinates_overflow_says_so_in_strict_json(huge_ply,
                                                                             capsys):
    report = validate_file(huge_ply)
    assert not report.passed
    assert report.problems == ("coordinates as large as 4e+300 (beyond 1e+100 volumes "
                               "overflow; wrong units?)",)
    # was: NaN volume and area, which `validate --json` cannot write (ValueError)
    assert main(["validate", str(huge_ply), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["passed"] is False and "coordinates as large" in doc["files"][0]["summary"]
