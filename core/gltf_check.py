"""glTF files that trimesh misreads or names badly, refused by name before it reads them.

Frames and units are not read here: only the file's JSON document (a GLB's first chunk).
"""

from __future__ import annotations

import json
import os
import urllib.parse

from .errors import MeshError


def _gltf_document(data: bytes) -> dict | None:
    """The JSON document of a GLB (its first chunk) or a .gltf file, or None where it is
    neither (the readers then say what is wrong)."""
    if data[:4] == b"glTF":
        size = int.from_bytes(data[12:16], "little")
        if data[16:20] != b"JSON":
            return None
        data = data[20:20 + size]
    try:
        document = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        return None
    return document if isinstance(document, dict) else None


def check_gltf(path: str, data: bytes, label: str) -> None:
    """Refuse the glTF files trimesh misreads or names badly, before it reads them.

    Draco-compressed meshes (``KHR_draco_mesh_compression``): trimesh cannot decode them and
    reads placeholder zeros (zero volume, degenerate faces) with a warning on stderr. A
    buffer file that is missing: trimesh's error is its bare name.

    Raises:
        MeshError: either of those, named.
    """
    document = _gltf_document(data)
    if document is None:
        return

    def listed(holder: object, key: str) -> list:
        """``holder[key]`` where both are what the format says (an object, a list)."""
        value = holder.get(key) if isinstance(holder, dict) else None
        return value if isinstance(value, list) else []

    def extensions(holder: object) -> dict:
        value = holder.get("extensions") if isinstance(holder, dict) else None
        return value if isinstance(value, dict) else {}

    draco = "KHR_draco_mesh_compression"
    if draco in listed(document, "extensionsUsed") + listed(document, "extensionsRequired") \
            or any(draco in extensions(primitive) for mesh in listed(document, "meshes")
                   for primitive in listed(mesh, "primitives")):
        raise MeshError(f"{label} is a Draco-compressed glTF, which is not read: export it "
                        "again without mesh compression (Blender: glTF export > Data > "
                        "Compression off).")
    for buffer in listed(document, "buffers"):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if not isinstance(uri, str) or uri.startswith("data:"):
            continue
        wanted = os.path.join(os.path.dirname(path), urllib.parse.unquote(uri))
        if not os.path.isfile(wanted):
            raise MeshError(f"{label} keeps its data in the buffer file '{uri}', which is "
                            f"missing ('{wanted}' does not exist): copy it beside the "
                            ".gltf, or export it again as .glb (one file).")
