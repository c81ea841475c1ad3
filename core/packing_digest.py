"""Whether a packing's placements are the ones its certificate vouches for.

Every certified packing records `placements_digest` in its certificate (key DIGEST) when it
is made; a packing file whose placements, frames, volumes or certificate were changed since
no longer matches it (`placements_status`), and its certificate then says nothing about it.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np

from .packing_json import to_jsonable
from .packing_types import Packing, is_spec

#: the certificate's key for `placements_digest`
DIGEST = "placements_sha256"


def placements_digest(p: Packing) -> str:
    """sha256 (hex) over what a packing's certificate vouches for: the placements (type
    index, rotation, translation, scale), the container's identity (sha256 or box spec),
    frame and volume, each type's sha256, local frame and volume, and the certificate's
    own values (without the digest). Floats hash as their exact binary64 value, which the
    packing JSON keeps, so a saved and loaded packing has the digest it was saved with."""
    h = hashlib.sha256(b"jampacked.placements.1\0")

    def add(a, dtype: str) -> None:
        a = np.ascontiguousarray(np.asarray(a, dtype=dtype))
        h.update(repr(a.shape).encode() + a.tobytes())

    container = p.container_sha256 if p.container_sha256 or not is_spec(p.container_path) \
        else p.container_path
    head = {"container": container, "types": [t.sha256 for t in p.types],
            "certificate": {k: v for k, v in to_jsonable(p.certificate, "certificate").items()
                            if k != DIGEST}}
    h.update(json.dumps(head, sort_keys=True, allow_nan=False).encode() + b"\0")
    add(p.frame_from_file, "<f8")
    add([p.container_volume, *(t.volume for t in p.types)], "<f8")
    add([t.local_from_file for t in p.types], "<f8")
    add(p.type_index, "<i8")
    add(p.rotations, "<f8")
    add(p.translations, "<f8")
    add(p.scales, "<f8")
    return h.hexdigest()


def record_digest(p: Packing) -> None:
    """Record in a certified packing's certificate the digest of what it vouches for (in
    place): when it is made, and when its maker renames or rescales what was certified."""
    if isinstance(p.certificate, dict) and p.certificate.get("certified") is True:
        p.certificate[DIGEST] = placements_digest(p)


def placements_status(p: Packing) -> str:
    """"as certified" (the certificate records this packing's digest, and the clearance
    its inputs ask is the one certified), "changed" (the packing was edited after it was
    certified), or "unrecorded" (no digest: not certified, or written by an older
    jampacked)."""
    recorded = p.certificate.get(DIGEST) if isinstance(p.certificate, dict) else None
    if not isinstance(recorded, str):
        return "unrecorded"
    if recorded != placements_digest(p) or clearance_changed(p):
        return "changed"
    return "as certified"


def clearance_changed(p: Packing) -> bool:
    """Whether the packing's inputs ask a larger clearance (which an export keeps, and which
    the digest does not cover) than its certificate vouches for; a smaller one holds."""
    certified = p.certificate.get("clearance") if isinstance(p.certificate, dict) else None
    asked = p.inputs.clearance
    return isinstance(certified, int | float) and isinstance(asked, int | float) \
        and float(asked) > float(certified)


def only_clearance_changed(p: Packing) -> bool:
    """Whether the packing is as certified but for a larger clearance asked."""
    return isinstance(p.certificate, dict) and clearance_changed(p) \
        and p.certificate.get(DIGEST) == placements_digest(p)


def claims_certified(p: Packing) -> bool:
    """Whether the packing says it was certified (a digest, or "certified": true)."""
    return isinstance(p.certificate, dict) and (
        isinstance(p.certificate.get(DIGEST), str) or p.certificate.get("certified") is True)


def uncertified_since(p: Packing) -> str | None:
    """Why a packing's certificate does not vouch for it, as a phrase after "the packing",
    or None where it does: edited after it was certified, asking a larger clearance than
    certified, claiming to be certified without the digest of what was (written by a
    jampacked before digests were recorded, or the digest was removed, which then hides any
    edit), or not certified at all (written by hand or by another tool, or with its
    certificate removed)."""
    status = placements_status(p)
    if status == "as certified":
        return None
    if only_clearance_changed(p):
        return (f"asks a clearance of {p.inputs.clearance:g}, but was certified with "
                f"{p.certificate.get('clearance'):g}")
    if status == "changed":
        return ("was changed after it was certified (its certificate's digest no longer "
                "matches its placements)")
    if claims_certified(p):
        return ("says it is certified but records no digest of what was certified (it was "
                "written by an older jampacked, or the digest was removed)")
    return "is not certified (its certificate does not say so, or it has none)"
