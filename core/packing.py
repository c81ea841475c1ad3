"""Packings, the one module to import them from: the result types and their JSON file.

`Packing` and `TypeRecord` (frames and units: `core/packing_types.py`), `save_packing` /
`load_packing` / `verify_sources` (the file: `core/packing_json.py`), and
`placement_matrices` (rotations: `core/rotations.py`). Modules inside the engine import
from those modules directly.
"""

from __future__ import annotations

from .packing_json import load_packing, save_packing, verify_sources
from .packing_types import Packing, TypeRecord, container_mesh, is_spec
from .rotations import placement_matrices

__all__ = ["Packing", "TypeRecord", "container_mesh", "is_spec", "load_packing",
           "placement_matrices", "save_packing", "verify_sources"]
