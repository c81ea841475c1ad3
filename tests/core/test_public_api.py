"""The import paths users, the README and outside tools (the fuzz harness) rely on."""

from __future__ import annotations

import importlib
import inspect

import pytest

PUBLIC = {
    "jampacked.core.api": ["pack"],
    "jampacked.core.errors": ["JampackedError", "InputError", "MeshError", "PackingError",
                              "Cancelled"],
    "jampacked.core.meshes": ["load_mesh", "MeshData", "mesh_from_arrays"],
    "jampacked.core.packing": ["Packing", "TypeRecord", "load_packing", "save_packing",
                               "verify_sources", "container_mesh", "placement_matrices"],
    "jampacked.export.assemble": ["export_packing", "ExportOptions"],
    "jampacked.export.options": ["ExportOptions", "Opening"],
    "jampacked.export.io": ["read_mesh_arrays", "write_mesh"],
    "jampacked.export.validate": ["validate_file", "validate_arrays"],
    "jampacked.cli.main": ["main"],
}


@pytest.mark.parametrize("module", sorted(PUBLIC))
def test_public_names(module):
    mod = importlib.import_module(module)
    missing = [n for n in PUBLIC[module] if not hasattr(mod, n)]
    assert not missing, f"{module} lacks {missing}"


def test_pack_keywords():
    params = inspect.signature(importlib.import_module("jampacked.core.api").pack).parameters
    for name in ("shares", "seed", "clearance", "fidelity", "time_budget", "progress",
                 "should_cancel", "container_size", "type_scale", "names", "use_cache"):
        assert name in params, name
