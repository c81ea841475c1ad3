"""Whether a batch scene's packing file can be trusted on a rerun (`check_done`): made for
the scene's meshes, seed and settings, its sources unchanged, certified, its placements the
ones certified (`packing_digest.placements_digest`, which every certified packing records
in its certificate) and its numbers what its placements give. A file that fails
is packed again, and the reason is shown.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .batch_file import SceneSpec
from .errors import JampackedError
from .metrics import compute_metrics
from .options import CavityPassOptions
from .packing_digest import DIGEST, clearance_changed, placements_digest, uncertified_since
from .packing_json import load_packing, verify_sources
from .packing_types import Packing

#: the numbers a skipped file's metrics must hold, recomputed from its placements
CHECKED_METRICS = ("count", "count_per_type", "density", "tvd", "nni_per_type", "nni_mean",
                   "shares")


def check_done(spec: SceneSpec, path: Path) -> tuple[Packing | None, str]:
    """The scene's packing file if it is done and verified, else None and why not (a
    sentence for the user: what is wrong with the file)."""
    if not path.is_file():
        return None, "not packed yet"
    try:
        p = load_packing(path)
    except JampackedError as exc:
        return None, f"unreadable: {exc}"
    if p.seed != spec.seed or len(p.types) != len(spec.types) or not all(
            _same_path(t.path, s) for t, s in zip(p.types, spec.types, strict=True)) \
            or not _same_path(p.container_path, spec.container):
        return None, "made for other meshes or another seed"
    changed = _changed_settings(spec, p)
    if changed:
        return None, f"made with a different '{changed}'"
    problems = verify_sources(p)
    if problems:
        return None, problems[0]
    if p.report.stopped == "cancelled":
        return None, "stopped by Ctrl-C before the end"
    if p.certificate.get("certified") is not True:
        return None, "not certified"
    recorded = p.certificate.get(DIGEST)
    if not isinstance(recorded, str):
        return None, ("its certificate records no digest of the certified placements (written "
                      "by an older jampacked), so they cannot be verified")
    if recorded != placements_digest(p):
        return None, ("its placements, frames, volumes or certificate were changed after it "
                      "was certified (the certificate's digest no longer matches)")
    if clearance_changed(p):  # the digest does not cover the clearance asked
        return None, f"it {uncertified_since(p)}"
    wrong = wrong_metric(p)
    if wrong:
        return None, wrong
    return p, ""


def wrong_metric(p: Packing, *, missing_ok: bool = False) -> str:
    """The first of the packing's numbers that its placements do not give ("" if none):
    counts, density (recorded type volumes over the container volume), TVD, NNI, shares.
    With ``missing_ok`` a number the file does not hold is not one of them (files written
    before it was recorded)."""
    if len(p.types) == 0:
        return "it lists no object types"
    shares = np.array([t.share for t in p.types], float)
    if not shares.sum() > 0:
        return "its types' shares do not add up to a positive number"
    should = compute_metrics(p.type_index, p.translations,
                             np.array([t.volume for t in p.types], float), shares,
                             p.container_volume)
    for key in CHECKED_METRICS:
        said, right = p.metrics.get(key), should[key]
        if missing_ok and key not in p.metrics:
            continue
        if not _same_number(said, right):
            return (f"its metrics.{key} reads {_short(said)} but its placements give "
                    f"{_short(right)} (edited after it was made?)")
    return ""


def _same_number(a, b) -> bool:
    """a (as read from a file) equals b (recomputed), to rounding; lists item by item."""
    if isinstance(b, list):
        return isinstance(a, list) and len(a) == len(b) and all(
            _same_number(x, y) for x, y in zip(a, b, strict=True))
    if b is None or a is None:
        return a is None and b is None
    if isinstance(a, bool) or not isinstance(a, int | float):
        return False
    return bool(np.isclose(float(a), float(b), rtol=1e-9, atol=1e-12))


def _short(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, list):
        return "[" + ", ".join(_short(x) for x in v) + "]"
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _changed_settings(spec: SceneSpec, p: Packing) -> str:
    """The first setting of `spec` that the packing was not made with ("" if none)."""
    i = p.inputs
    given = {"clearance": (i.clearance, spec.clearance), "fidelity": (i.fidelity, spec.fidelity),
             "time_budget": (i.time_budget, spec.time_budget),
             "container_size": (i.container_size, spec.container_size),
             "type_scale": (i.type_scale, spec.type_scale),
             "attempts": (i.options.attempts.count, spec.attempts),
             "mix_tolerance": (i.options.cavity.max_tvd, spec.mix_tolerance
                               if spec.mix_tolerance is not None
                               else CavityPassOptions().max_tvd)}
    for name, (made, asked) in given.items():
        if made != asked:
            return name
    # no shares in the batch file: pack() gives every type an equal one
    asked = spec.shares if spec.shares is not None else [1.0] * len(spec.types)
    q = np.asarray(asked, float) / sum(asked)
    made = [t.share for t in p.types]
    if len(made) != len(q) or not np.allclose(made, q, rtol=1e-9, atol=1e-12):
        return "shares"
    return ""


def _same_path(a: str | None, b: str) -> bool:
    return a is not None and (a == b or os.path.realpath(a) == os.path.realpath(b))
