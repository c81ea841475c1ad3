"""Run the scenes of a batch (`core/batch_file.py`): locally one after another, or on a Dask
cluster's workers; each packing written from this process only, atomically, as
``<out>/<scene id>.json``, plus a summary (``summary.csv``).

A scene whose file is already there and verified (`core/batch_verify.py`: made for the
scene, its sources unchanged, certified, its placements the ones certified, its numbers
what they give) is skipped; any other file is packed again, and the result says why. This
module records the digest of what it certified when it saves a packing. A scene's exports
are made again where their record does not vouch for them (`core/batch_exports.py`). On a
cluster a worker runs `pack_scene` and returns the Packing; a worker that dies mid-scene
has its scenes run again elsewhere by Dask's scheduler, and since only this process writes,
by scene id, a scene is never lost nor written twice. Cancel (Ctrl-C) stops: finished
scenes stay written; the scene packing here writes its best certified packing so far,
which a rerun packs again (`check_done`); scenes on a cluster's workers are dropped.
"""

from __future__ import annotations

import csv
import io
import os
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from .api import pack
from .atomic import atomic_output, refusal_advice, write_refusal
from .batch_exports import drop_outdated, export_scene, exports_record, recorded_exports
from .batch_file import SceneSpec
from .batch_verify import check_done
from .errors import InputError, JampackedError, OutputError
from .options import CavityPassOptions, PackOptions
from .packing_digest import DIGEST
from .packing_json import save_packing
from .packing_types import Packing
from .summary import number

SUMMARY = "summary.csv"
COLUMNS = ("id", "status", "seed", "container", "types", "count", "density", "tvd",
           "nni_mean", "certified", "seconds", "file", "batch", "folder", "message")
#: what a scene stopped by Ctrl-C while packing says in the summary
CANCELLED_NOTE = ("stopped by Ctrl-C before the end: its best certified packing so far is "
                  "written, not exported, and the next run packs it again")
#: what a scene whose export Ctrl-C stopped says
EXPORT_CANCELLED_NOTE = ("its packing is written; Ctrl-C stopped its export, which the next "
                         "run makes")
#: seconds between looks at the cluster's futures and the cancel callback
POLL = 0.1


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
    #: what became of earlier runs' export files that are no longer this scene's
    #: ("removed scene.stl: ...", or why one was left)
    removed: list[str] = field(default_factory=list)
    #: the warnings of its export (as `jampacked export` prints them)
    export_warnings: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """The run's warnings on its packing (as `jampacked pack` prints them), then its
        export's."""
        packed = [] if self.packing is None else list(self.packing.report.warnings)
        return packed + [f"export: {w}" for w in self.export_warnings]

    def notes(self) -> list[str]:
        """What the user should read about this scene, beyond its status and numbers: the
        error, why it was packed again, its run's warnings."""
        out = [self.message] if self.message else []
        if self.repacked:
            out.append(f"packed again: the earlier file was not trusted: {self.repacked}")
        out += [f"exported again: {r}" for r in self.reexported]
        out += self.removed
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
                "seconds": _fmt(self.seconds), "file": Path(self.file).name if self.file else "",
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


@dataclass(frozen=True)
class SceneFailure:
    """A scene the engine refused on a worker, returned rather than raised: Dask logs a
    task's exception with its traceback on the console, which a user's mistake (a mesh
    that does not fit) does not merit."""

    message: str


def pack_scene_on_worker(spec: SceneSpec) -> Packing | SceneFailure:
    """`pack_scene` as a cluster's worker runs it: the engine's errors come back as values."""
    try:
        return pack_scene(spec)
    except JampackedError as exc:
        return SceneFailure(str(exc))


def scene_file(out_dir: str | os.PathLike, spec: SceneSpec) -> Path:
    return Path(out_dir) / f"{spec.id}.json"


def run_batch(scenes: list[SceneSpec], out_dir: str | os.PathLike, client=None,
              progress: Callable[[int, int, str], None] | None = None,
              should_cancel: Callable[[], bool] | None = None,
              checked: dict[str, tuple[Packing | None, str]] | None = None,
              batch: str = "") -> list[SceneResult]:
    """Pack every scene not already done and verified in `out_dir`; returns one result per
    scene, in the batch's order, and writes `out_dir`/summary.csv. client: a
    distributed.Client (its workers run the scenes) or None (here, one after another).
    progress(done, total, message) after each scene; should_cancel() is polled. checked:
    `check_done` of scenes by id, where the caller has already run it. batch: the batch
    file's path, which the summary's rows record (a rerun of that file replaces all of its
    rows, so that a scene taken out of it leaves the summary)."""
    check_output(scenes, out_dir, batch)
    out = Path(out_dir)
    _check_other_batches(scenes, out, batch)
    if not out.is_dir():
        try:
            out.mkdir(parents=True)
        except OSError as exc:
            raise InputError(f"cannot create output folder {out}: {exc.strerror or exc}. "
                             "Give another folder with -o.") from None
        check_output(scenes, out, batch)
    report = progress or (lambda d, t, m: None)
    cancel = should_cancel or (lambda: False)
    results: dict[str, SceneResult] = {}
    todo = []
    why_not: dict[str, str] = {}
    for spec in scenes:
        path = scene_file(out, spec)
        done, why = (checked or {}).get(spec.id) or check_done(spec, path)
        if path.exists():
            why_not[spec.id] = why
        if done is not None:
            results[spec.id] = SceneResult(spec, "skipped", str(path), done,
                                           seconds=number(done.timings.get("total")))
            _export(results[spec.id], out, cancel, stale_only=True)
        else:
            todo.append(spec)
    total = len(scenes)
    report(len(results), total, f"{len(results)} already done, {len(todo)} to pack")

    def earlier(spec: SceneSpec) -> str:
        """What a scene not written this run says of the file an earlier run left."""
        path = scene_file(out, spec)
        if not path.exists():
            return ""
        exports = recorded_exports(out, spec)
        beside = (f" So are its exports beside it ({', '.join(exports)}): print none of "
                  "them for this scene." if exports else "")
        return (f" {path.name} is an earlier run's file, not this scene's packing "
                f"({why_not.get(spec.id) or 'not verified'}); left as it was.{beside}")

    def finish(spec: SceneSpec, packing: Packing | None, error: str = "") -> None:
        if packing is None:
            results[spec.id] = SceneResult(spec, "failed", message=error + earlier(spec))
        elif packing.report.stopped == "cancelled" and packing.n == 0:
            results[spec.id] = SceneResult(spec, "cancelled", message=(
                "stopped before any object was placed; not written." + earlier(spec)))
        else:
            path = scene_file(out, spec)
            try:
                save_packing(packing, path)
            except OutputError as exc:
                raise InputError(f"{exc} Finished scenes stay written: run the batch again "
                                 "once it can be written.") from None
            seconds = number(packing.timings.get("total"))
            if packing.report.stopped == "cancelled":  # kept, not exported, packed again
                results[spec.id] = SceneResult(
                    spec, "cancelled", str(path), packing, CANCELLED_NOTE, seconds,
                    removed=drop_outdated(spec, packing.certificate.get(DIGEST), out))
            else:
                results[spec.id] = SceneResult(spec, "packed", str(path), packing,
                                               seconds=seconds,
                                               repacked=why_not.get(spec.id, ""))
                _export(results[spec.id], out, cancel)
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
        write_summary(ordered, out / SUMMARY, batch)
    return ordered


def output_paths(spec: SceneSpec, out: Path) -> list[Path]:
    """The files a scene writes in `out`: its packing and its exports."""
    exports = [out / f"{spec.id}.{fmt}" for fmt in spec.export]
    return [scene_file(out, spec), *exports, *([exports_record(out, spec)] if exports else [])]


def _check_other_batches(scenes: list[SceneSpec], out: Path, batch: str) -> None:
    """Refuse, before anything is packed, a scene whose id another batch file (still there)
    wrote in `out` (its summary's row says which): each run of either file would pack it
    again for its own settings and replace the other's packing and row. A row that names
    the folder it was written in (its ``folder``) and names another folder was copied here
    with a project (its batch file is this one's original); a row of an older summary,
    without it, counts only where the other batch file lies beside this one."""
    if not batch:
        return
    ids = {spec.id for spec in scenes}
    here = os.path.dirname(batch)
    for row in _summary_rows(out / SUMMARY):
        other = row.get("batch") or ""
        folder = row.get("folder") or ""
        written_here = (_same_folder(folder, out) if folder
                        else os.path.dirname(other) == here)
        if (row["id"] in ids and other and other != batch and written_here
                and os.path.isfile(other) and not os.path.samefile(other, batch)):
            raise InputError(
                f"scene '{row['id']}' in {out} was written by another batch file, {other} "
                f"(the batch column of {out / SUMMARY}): two batch files writing one scene "
                "replace each other's packing on every run. Give the scene another name in "
                "one of them, or write this batch to another folder (-o).")


def _same_folder(recorded: str, out: Path) -> bool:
    """Whether the folder a summary row recorded is `out` (the same folder by another path
    too)."""
    try:
        return os.path.samefile(recorded, out)
    except OSError:  # gone, or not there: moved or copied since
        return False


def check_output(scenes: list[SceneSpec], out_dir: str | os.PathLike,
                 batch: str | os.PathLike = "") -> None:
    """Refuse, before anything is packed, an output folder the batch cannot write in: a
    file where the folder should be, a folder (or its nearest existing parent, when it is
    not there yet) that refuses new files (permissions, an immutable attribute, a
    read-only disk), a folder where a packing, an export or the summary is to go, or an
    input (the batch file, a scene's mesh) where one is to go. Raises InputError naming the
    path and how to fix it."""
    out = Path(out_dir)
    if not str(out_dir).strip():
        raise InputError("the output folder (-o) is empty: give a folder, e.g. -o out (it "
                         "is created if missing).")
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
    refused = write_refusal(out)
    if refused:
        raise InputError(f"cannot write in output folder {out}: {refused}. "
                         f"{refusal_advice(out)} or give another folder with -o.")
    inputs = _file_ids(_input_files(scenes, batch))
    for spec in scenes:
        for path in [*output_paths(spec, out), out / SUMMARY]:
            what = "its summary" if path.name == SUMMARY else f"scene {spec.id}"
            if path.is_dir():
                raise InputError(
                    f"{path} is a folder, but the batch writes {what} there. Move or remove "
                    "that folder, or give another folder with -o.")
            if _file_ids([path]) & inputs:
                raise InputError(
                    f"{path} is an input of the batch (its batch file or a mesh), but the "
                    f"batch writes {what} there, which would replace it. Give another "
                    "folder with -o, or rename the input.")


def _file_ids(paths: list) -> set[tuple[int, int]]:
    """The (device, inode) of each of `paths` that exists: one file by any name (a link,
    another case on a file system that ignores it) has one."""
    ids = set()
    for p in paths:
        try:
            st = os.stat(p)
        except OSError:
            continue
        ids.add((st.st_dev, st.st_ino))
    return ids


def _input_files(scenes: list[SceneSpec], batch: str | os.PathLike) -> list[str]:
    """The files a batch reads: its batch file and its scenes' meshes (not box specs)."""
    files = [os.fspath(batch)] if batch else []
    for spec in scenes:
        files += [p for p in (spec.container, *spec.types) if os.path.isfile(p)]
    return files


def _export(result: SceneResult, out: Path, cancel: Callable[[], bool],
            stale_only: bool = False) -> None:
    """`export_scene` of a written result; a failed export turns it into "failed", its
    packing kept, and the files made again are noted on it."""
    digest = None if result.packing is None else result.packing.certificate.get(DIGEST)
    error, again, removed, warned = export_scene(result.spec, result.file, digest, out,
                                                 cancel, stale_only)
    result.reexported += again
    result.removed += removed
    result.export_warnings = warned
    if error and cancel():
        result.status, result.message = "cancelled", EXPORT_CANCELLED_NOTE
    elif error:
        result.status, result.message = "failed", error


def _run_on_cluster(client, todo: list[SceneSpec], finish, cancel: Callable[[], bool]
                    ) -> None:
    token = uuid.uuid4().hex[:8]
    futures = {client.submit(pack_scene_on_worker, spec, key=f"scene-{spec.id}-{token}",
                             pure=False):
               spec for spec in todo}
    pending = dict(futures)
    try:
        while pending:
            stop = cancel()
            # scenes that finished while the last one was written are kept, even on cancel
            for f in [f for f in pending if f.done()]:
                spec = pending.pop(f)
                try:
                    packing = f.result()
                except JampackedError as exc:
                    finish(spec, None, str(exc))
                except Exception as exc:  # noqa: BLE001 - the scene's worker failed
                    # (Dask's KilledWorker after it died on every worker tried, a worker
                    # out of memory): that scene fails, the others go on
                    finish(spec, None, f"its worker failed: {type(exc).__name__}: {exc}")
                else:
                    if isinstance(packing, SceneFailure):
                        finish(spec, None, packing.message)
                    else:
                        finish(spec, packing)
                f.release()
            if stop:
                return
            time.sleep(POLL)
    finally:
        if pending:
            client.cancel(list(pending))


def write_summary(results: list[SceneResult], path: str | os.PathLike, batch: str = ""
                  ) -> None:
    """The batch's summary table as CSV (one row per scene), written atomically. Rows the
    file holds of other batch files run into the same folder are kept first, as they were;
    the rows of this batch file (``batch``, its path) are replaced by this run's."""
    ids = {r.spec.id for r in results}
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in _summary_rows(path):
        if row.get("id") not in ids and not (batch and row.get("batch") == batch):
            w.writerow({k: row.get(k) or "" for k in COLUMNS})
    folder = str(Path(path).parent.resolve()) if batch else ""
    for r in results:
        w.writerow({**r.row(), "batch": batch, "folder": folder})
    try:
        with atomic_output(path, "w") as f:
            f.write(buf.getvalue())
    except OSError as exc:
        raise InputError(f"cannot write the batch's summary {path}: {exc.strerror or exc}."
                         ) from None


def _summary_rows(path: str | os.PathLike) -> list[dict]:
    """The rows of an earlier summary at `path`, or [] when there is none readable. A
    spreadsheet may have saved it with semicolons or tabs between the fields (as Excel does
    where the decimal mark is a comma), and in the Windows code page."""
    try:
        raw = Path(path).read_bytes()
    except OSError:
        return []
    try:
        text = raw.decode("utf-8-sig")  # as a spreadsheet saves it
    except UnicodeDecodeError:  # Excel's "CSV" on Windows: the system's code page
        text = raw.decode("cp1252", errors="replace")
    try:
        header = text.partition("\n")[0]
        delimiter = max(",;\t", key=header.count)
        rows = list(csv.DictReader(io.StringIO(text, newline=""), delimiter=delimiter))
    except csv.Error:
        return []
    return [r for r in rows if isinstance(r.get("id"), str) and r["id"]]
