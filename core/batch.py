"""Run the scenes of a batch (`core/batch_file.py`): locally one after another, or on a Dask
cluster's workers; each packing written from this process only, atomically, as
``<out>/<scene id>.json``, plus a summary (``summary.csv``).

A scene whose file is already there and verified is skipped: it loads, names the scene's
seed, mesh files and settings, its sources' sha256 still match, it is certified, the digest
its certificate records (`placements_digest`, written by this module when it saves a
certified packing) still matches its placements, frames and volumes, and its numbers
(count, per-type counts, density, TVD, NNI) are what its placements give. A file that fails
any of these (edited by hand, written by `pack` or by an older jampacked without a digest)
is packed again, and the result says why. A scene's exports are recorded beside them
(``<out>/<scene id>.exports.json``: the packing's digest, the export settings, each file's
sha256); a rerun makes again the ones that record does not vouch for. On a cluster a
worker runs `pack_scene` and returns the Packing; a worker that dies mid-scene has its
scenes run again elsewhere by Dask's scheduler, and since only this process writes, by scene
id, a scene is never lost nor written twice. Cancel (Ctrl-C) stops waiting: finished
scenes stay written, unfinished ones are not written.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import tempfile
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .api import pack
from .atomic import atomic_output
from .batch_file import SceneSpec
from .errors import InputError, JampackedError
from .mesh_files import file_sha256
from .metrics import compute_metrics
from .options import CavityPassOptions, PackOptions
from .packing_json import load_packing, save_packing, to_jsonable, verify_sources
from .packing_types import Packing, is_spec

SUMMARY = "summary.csv"
COLUMNS = ("id", "status", "seed", "container", "types", "count", "density", "tvd",
           "nni_mean", "certified", "seconds", "file", "message")
#: seconds between looks at the cluster's futures and the cancel callback
POLL = 0.1
#: the certificate's key for `placements_digest`
DIGEST = "placements_sha256"
#: the numbers a skipped file's metrics must hold, recomputed from its placements
CHECKED_METRICS = ("count", "count_per_type", "density", "tvd", "nni_per_type", "nni_mean",
                   "shares")


@dataclass
class SceneResult:
    """What became of one scene: status "packed", "skipped" (already done and verified),
    "failed" (the engine refused, or its export failed: message) or "cancelled"."""

    spec: SceneSpec
    status: str
    file: str = ""
    packing: Packing | None = None
    message: str = ""
    seconds: float | None = None
    #: why an earlier file of the scene was not trusted and the scene packed again
    repacked: str = ""
    #: the export files made again on a skip, each with why ("scene.stl: missing")
    reexported: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """The run's warnings on its packing (as `jampacked pack` prints them)."""
        return [] if self.packing is None else list(self.packing.report.warnings)

    def notes(self) -> list[str]:
        """What the user should read about this scene, beyond its status and numbers: the
        error, why it was packed again, its run's warnings."""
        out = [self.message] if self.message else []
        if self.repacked:
            out.append(f"packed again: the earlier file was not trusted: {self.repacked}")
        out += [f"exported again: {r}" for r in self.reexported]
        return out + [f"warning: {w}" for w in self.warnings()]

    def row(self) -> dict:
        p, s = self.packing, self.spec
        m = p.metrics if p is not None else {}
        return {"id": s.id, "status": self.status, "seed": s.seed, "container": s.container,
                "types": ";".join(s.types),
                "count": p.n if p is not None else "",
                "density": _fmt(m.get("density")), "tvd": _fmt(m.get("tvd")),
                "nni_mean": _fmt(m.get("nni_mean")),
                "certified": "" if p is None else p.certificate.get("certified"),
                "seconds": _fmt(self.seconds), "file": self.file,
                "message": " | ".join(self.notes())}


def _fmt(v) -> str:
    return "" if v is None else f"{float(v):.6g}"


def pack_scene(spec: SceneSpec, should_cancel: Callable[[], bool] | None = None) -> Packing:
    """The packing of one scene (what a worker runs)."""
    options = None
    if spec.mix_tolerance is not None:
        options = PackOptions(cavity=CavityPassOptions(max_tvd=spec.mix_tolerance))
    return pack(spec.container, list(spec.types), spec.shares, seed=spec.seed,
                clearance=spec.clearance, fidelity=spec.fidelity,
                time_budget=spec.time_budget, container_size=spec.container_size,
                type_scale=spec.type_scale, options=options, attempts=spec.attempts,
                should_cancel=should_cancel)


def scene_file(out_dir: str | os.PathLike, spec: SceneSpec) -> Path:
    return Path(out_dir) / f"{spec.id}.json"


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
        return None, f"made with another {changed}"
    problems = verify_sources(p)
    if problems:
        return None, problems[0]
    if p.certificate.get("certified") is not True:
        return None, "not certified"
    recorded = p.certificate.get(DIGEST)
    if not isinstance(recorded, str):
        return None, ("its certificate records no digest of the certified placements (written "
                      "by 'jampacked pack' or an older jampacked), so they cannot be verified")
    if recorded != placements_digest(p):
        return None, ("its placements, frames, volumes or certificate were changed after it "
                      "was certified (the certificate's digest no longer matches)")
    wrong = _wrong_metric(p)
    if wrong:
        return None, wrong
    return p, ""


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


def _wrong_metric(p: Packing) -> str:
    """The first of the packing's numbers that its placements do not give ("" if none):
    counts, density (recorded type volumes over the container volume), TVD, NNI, shares."""
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
    if spec.shares is not None:
        q = np.asarray(spec.shares, float) / sum(spec.shares)
        if not np.allclose([t.share for t in p.types], q, rtol=1e-9, atol=1e-12):
            return "shares"
    return ""


def _same_path(a: str | None, b: str) -> bool:
    return a is not None and (a == b or os.path.realpath(a) == os.path.realpath(b))


def run_batch(scenes: list[SceneSpec], out_dir: str | os.PathLike, client=None,
              progress: Callable[[int, int, str], None] | None = None,
              should_cancel: Callable[[], bool] | None = None) -> list[SceneResult]:
    """Pack every scene not already done and verified in `out_dir`; returns one result per
    scene, in the batch's order, and writes `out_dir`/summary.csv. client: a
    distributed.Client (its workers run the scenes) or None (here, one after another).
    progress(done, total, message) after each scene; should_cancel() is polled."""
    out = Path(out_dir)
    check_output(scenes, out)
    if not out.is_dir():
        try:
            out.mkdir(parents=True)
        except OSError as exc:
            raise InputError(f"cannot create output folder {out}: {exc.strerror or exc}. "
                             "Give another folder with -o.") from None
        check_output(scenes, out)
    report = progress or (lambda d, t, m: None)
    cancel = should_cancel or (lambda: False)
    results: dict[str, SceneResult] = {}
    todo = []
    why_not: dict[str, str] = {}
    for spec in scenes:
        path = scene_file(out, spec)
        done, why = check_done(spec, path)
        if path.exists():
            why_not[spec.id] = why
        if done is not None:
            results[spec.id] = SceneResult(spec, "skipped", str(path), done,
                                           seconds=done.timings.get("total"))
            export_scene(results[spec.id], out, cancel, stale_only=True)
        else:
            todo.append(spec)
    total = len(scenes)
    report(len(results), total, f"{len(results)} already done, {len(todo)} to pack")

    def finish(spec: SceneSpec, packing: Packing | None, error: str = "") -> None:
        if packing is None:
            results[spec.id] = SceneResult(spec, "failed", message=error)
        elif packing.report.stopped == "cancelled":
            results[spec.id] = SceneResult(spec, "cancelled", packing=None,
                                           message="stopped before the end; not written")
        else:
            path = scene_file(out, spec)
            if packing.certificate.get("certified") is True:
                packing.certificate[DIGEST] = placements_digest(packing)
            try:
                save_packing(packing, path)
            except OSError as exc:
                raise InputError(f"cannot write {path}: {exc.strerror or exc}; finished "
                                 "scenes stay written. Free the folder and run the batch "
                                 "again.") from None
            results[spec.id] = SceneResult(spec, "packed", str(path), packing,
                                           seconds=packing.timings.get("total"),
                                           repacked=why_not.get(spec.id, ""))
            export_scene(results[spec.id], out, cancel)
        report(len(results), total, f"{spec.id}: {results[spec.id].status}")

    try:
        if client is None:
            for spec in todo:
                if cancel():
                    break
                try:
                    finish(spec, pack_scene(spec, cancel))
                except JampackedError as exc:
                    finish(spec, None, str(exc))
        else:
            _run_on_cluster(client, todo, finish, cancel)
    finally:
        for spec in scenes:
            results.setdefault(spec.id, SceneResult(spec, "cancelled",
                                                    message="not run (cancelled)"))
        ordered = [results[s.id] for s in scenes]
        write_summary(ordered, out / SUMMARY)
    return ordered


def output_paths(spec: SceneSpec, out: Path) -> list[Path]:
    """The files a scene writes in `out`: its packing and its exports."""
    exports = [out / f"{spec.id}.{fmt}" for fmt in spec.export]
    return [scene_file(out, spec), *exports, *([exports_record(out, spec)] if exports else [])]


def check_output(scenes: list[SceneSpec], out_dir: str | os.PathLike) -> None:
    """Refuse, before anything is packed, an output folder the batch cannot write in: a
    file where the folder should be, a folder (or its nearest existing parent, when it is
    not there yet) that refuses new files (permissions, an immutable attribute, a
    read-only disk), or a folder where a packing, an export or the summary is to go.
    Raises InputError naming the path and how to fix it."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"output folder {out} is a file, not a folder; give a folder with "
                         "-o (it is created if missing).")
    if not out.is_dir():
        parent = next((p for p in out.absolute().parents if p.exists()), None)
        if parent is not None and not parent.is_dir():
            raise InputError(f"cannot create output folder {out}: {parent} is a file, not a "
                             "folder. Give another folder with -o.")
        if parent is not None and not os.access(parent, os.W_OK | os.X_OK):
            raise InputError(f"cannot create output folder {out}: {parent} is not writable. "
                             "Make it writable or give another folder with -o.")
        return
    try:
        fd, probe = tempfile.mkstemp(prefix=".jampacked-write-test.", dir=out)
    except OSError as exc:
        raise InputError(
            f"cannot write in output folder {out}: {exc.strerror or exc}. Make it writable "
            f"(e.g. chmod u+w {out}; 'lsattr -d {out}' shows an immutable 'i' flag, which "
            f"'chattr -i {out}' removes) or give another folder with -o.") from None
    os.close(fd)
    os.unlink(probe)
    for spec in scenes:
        for path in [*output_paths(spec, out), out / SUMMARY]:
            if path.is_dir():
                raise InputError(
                    f"{path} is a folder, but the batch writes "
                    f"{'its summary' if path.name == SUMMARY else f'scene {spec.id}'} "
                    "there. Move or remove that folder, or give another folder with -o.")


#: the record, beside a scene's exports, of how they were made: OUT/<id>.exports.json
EXPORTS_FORMAT = "jampacked.batch-exports"


def exports_record(out: Path, spec: SceneSpec) -> Path:
    return out / f"{spec.id}.exports.json"


def export_scene(result: SceneResult, out: Path, cancel: Callable[[], bool],
                 stale_only: bool = False) -> None:
    """Export a written packing to the formats its scene asks for (`out`/<id>.<format>,
    validated and written atomically by `export_packing`) and record how (`exports_record`:
    the packing's digest, the export settings, each file's sha256). `stale_only`: only the
    files that record does not vouch for: missing, changed since written (truncated,
    edited), made from another packing or with other settings (export_mode, export_shell),
    or from before the record; why is noted on the result. A failed export turns the result
    into "failed", its packing kept."""
    spec = result.spec
    if not spec.export:
        return
    settings = {"mode": spec.export_mode, "shell": spec.export_shell}
    digest = None if result.packing is None else result.packing.certificate.get(DIGEST)
    record = _read_record(exports_record(out, spec))
    made = record.get("files", {}) if (record.get("packing") == digest
                                       and record.get("settings") == settings) else {}
    paths = [out / f"{spec.id}.{fmt}" for fmt in spec.export]
    if stale_only:
        stale = []
        for path in paths:
            why = _stale_export(path, record, made, settings, digest)
            if why:
                stale.append(path)
                result.reexported.append(f"{path.name}: {why}")
        paths = stale
        made = {k: v for k, v in made.items() if k not in {p.name for p in paths}}
    else:
        made = {}
    if not paths:
        return
    from jampacked.export.assemble import export_packing
    from jampacked.export.options import ExportOptions

    try:
        rep = export_packing(result.file, [str(p) for p in paths], ExportOptions(
            mode=spec.export_mode, shell=spec.export_shell), should_cancel=cancel)
    except JampackedError as exc:
        result.status, result.message = "failed", f"export: {exc}"
        rep = None
    if rep is not None and not rep.passed:
        result.status, result.message = "failed", "export: a file did not validate"
    elif rep is not None:
        made.update({p.name: file_sha256(p) for p in paths})
    _write_record(exports_record(out, spec), {
        "format": EXPORTS_FORMAT, "version": 1, "packing": digest, "settings": settings,
        "files": made})


def _stale_export(path: Path, record: dict, made: dict, settings: dict,
                  digest: str | None) -> str:
    """Why the export file at `path` must be made again ("" if its record vouches for it)."""
    if not path.is_file():
        return "missing"
    if not record:
        return "no record of how it was made (exported by an older jampacked)"
    if record.get("packing") != digest:
        return "made from another packing"
    if record.get("settings") != settings:
        old = record.get("settings") or {}
        changed = [f"export_{k} {old.get(k)!r} -> {v!r}" for k, v in settings.items()
                   if old.get(k) != v]
        return "made with " + (", ".join(changed) or "other settings")
    if path.name not in made:
        return "no record of how it was made"
    try:
        if file_sha256(path) != made[path.name]:
            return "changed since it was written and validated (truncated or edited?)"
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    return ""


def _read_record(path: Path) -> dict:
    """The exports record at `path`, or {} when it is missing or not one."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(doc, dict) or doc.get("format") != EXPORTS_FORMAT \
            or not isinstance(doc.get("files"), dict):
        return {}
    return doc


def _write_record(path: Path, doc: dict) -> None:
    try:
        with atomic_output(path, "w") as f:
            f.write(json.dumps(doc, indent=1) + "\n")
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}.") from None


def _run_on_cluster(client, todo: list[SceneSpec], finish, cancel: Callable[[], bool]
                    ) -> None:
    token = uuid.uuid4().hex[:8]
    futures = {client.submit(pack_scene, spec, key=f"scene-{spec.id}-{token}", pure=False):
               spec for spec in todo}
    pending = dict(futures)
    try:
        while pending:
            if cancel():
                return
            for f in [f for f in pending if f.done()]:
                spec = pending.pop(f)
                try:
                    packing = f.result()
                except JampackedError as exc:
                    finish(spec, None, str(exc))
                else:
                    finish(spec, packing)
                f.release()
            time.sleep(POLL)
    finally:
        if pending:
            client.cancel(list(pending))


def write_summary(results: list[SceneResult], path: str | os.PathLike) -> None:
    """The batch's summary table as CSV (one row per scene), written atomically."""
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for r in results:
        w.writerow(r.row())
    try:
        with atomic_output(path, "w") as f:
            f.write(buf.getvalue())
    except OSError as exc:
        raise InputError(f"cannot write the batch's summary {path}: {exc.strerror or exc}."
                         ) from None
