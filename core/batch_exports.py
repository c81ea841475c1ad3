"""A batch scene's export files and the record of how they were made
(``<out>/<scene id>.exports.json``: the packing's digest, the export settings, each file's
sha256 as written and validated); a rerun makes again the files that record does not vouch
for.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from .atomic import atomic_output
from .batch_file import SceneSpec
from .errors import InputError, JampackedError
from .mesh_files import file_sha256

#: the record, beside a scene's exports, of how they were made: OUT/<id>.exports.json
EXPORTS_FORMAT = "jampacked.batch-exports"


def exports_record(out: Path, spec: SceneSpec) -> Path:
    return out / f"{spec.id}.exports.json"


def export_scene(spec: SceneSpec, packing_file: str, digest: str | None, out: Path,
                 cancel: Callable[[], bool], stale_only: bool = False
                 ) -> tuple[str, list[str], list[str], list[str]]:
    """Export a scene's written packing (`packing_file`, whose certificate's digest is
    `digest`) to the formats the scene asks for (`out`/<id>.<format>, validated and written
    by `export_packing`: all or none) and record how (`exports_record`: the packing's
    digest, the export settings, each file's sha256). `stale_only`: only the files that
    record does not vouch for: missing, changed since written (truncated, edited), made from
    another packing or with other settings (export_mode, export_shell), or from before the
    record. Files the record lists from another packing or settings that were not made
    again are removed (`drop_outdated`), and so are those of a format the scene no longer
    asks for, unchanged since written. Returns the error ("" if none: a
    failed export leaves the packing as it is), why each file was made again (with
    `stale_only`), the files removed, with why, and the export's warnings (sealed voids,
    loose bodies: as `jampacked export` prints them; kept in the record for the runs that
    make nothing)."""
    settings = _settings(spec)
    record = _read_record(exports_record(out, spec))
    made = record.get("files", {}) if _current(record, digest, spec) else {}
    paths = [out / f"{spec.id}.{fmt}" for fmt in spec.export]
    asked = {p.name for p in paths}
    # a format taken out of the scene's `export`: its file goes, unchanged since written
    unasked = "its format is no longer asked for"
    dropped = _remove_recorded(out, made, asked, unasked, unasked)
    if any(name not in asked for name in made):  # the record lists only what is asked
        made = {k: v for k, v in made.items() if k in asked}
        record = {**record, "files": made}
        if made or spec.export or not all(note.startswith("removed") for note in dropped):
            _write_record(exports_record(out, spec), record)
        else:  # it describes nothing now
            exports_record(out, spec).unlink(missing_ok=True)
            record = {}
    if not spec.export:
        return "", [], dropped + drop_outdated(spec, digest, out, record=record), []
    again: list[str] = []
    if stale_only:
        stale = []
        for path in paths:
            why = _stale_export(path, record, made, settings, digest)
            if why:
                stale.append(path)
                again.append(f"{path.name}: {why}")
        paths = stale
        made = {k: v for k, v in made.items() if k not in {p.name for p in paths}}
    else:
        made = {}
    if not paths:
        return "", again, dropped, (_recorded_warnings(record)
                                    if _current(record, digest, spec) else [])
    from jampacked.export.assemble import export_packing
    from jampacked.export.options import ExportOptions

    error = ""
    warned: list[str] = []
    try:
        rep = export_packing(packing_file, [str(p) for p in paths], ExportOptions(
            mode=spec.export_mode, shell=spec.export_shell), should_cancel=cancel)
    except JampackedError as exc:
        error = f"export: {exc}"
    else:
        warned = list(rep.warnings)
        if rep.passed:
            made.update({p.name: file_sha256(p) for p in paths})
        else:
            error = "export: a file did not validate"
    if error and made:  # the files kept from before keep their export's warnings
        warned = _recorded_warnings(record)
    _write_record(exports_record(out, spec), {
        "format": EXPORTS_FORMAT, "version": 1, "packing": digest, "settings": settings,
        "files": made, "warnings": warned})
    return error, again, dropped + drop_outdated(spec, digest, out, set(made), record), warned


def _remove_recorded(out: Path, files: dict, keep: set[str] | frozenset[str], why: str,
                     removed: str) -> list[str]:
    """Remove the export files a record lists (`files`: name -> sha256 as written) but
    `keep`, where unchanged since written; those changed since are left. `why`: what makes
    them outdated, `removed`: the note of one removed. Returns what was removed or left,
    with why."""
    notes = []
    for name, sha in files.items():
        path = out / str(name)
        if name in keep or path.name != name or not path.is_file():
            continue  # kept, not a plain name in `out`, or gone
        try:
            if file_sha256(path) != sha:
                notes.append(f"left {name}: {why}, but changed since")
                continue
            path.unlink()
        except OSError as exc:
            notes.append(f"could not remove {name} ({why}): {exc.strerror or exc}")
            continue
        notes.append(f"removed {name}: {removed}")
    return notes


def recorded_exports(out: Path, spec: SceneSpec) -> list[str]:
    """The names of the export files the scene's record lists that are in `out`."""
    files = _read_record(exports_record(out, spec)).get("files", {})
    return [str(name) for name in files if (out / str(name)).is_file()]


def _recorded_warnings(record: dict) -> list[str]:
    """The export warnings an exports record keeps (none where it keeps no list of them)."""
    warned = record.get("warnings")
    return [w for w in warned if isinstance(w, str)] if isinstance(warned, list) else []


def drop_outdated(spec: SceneSpec, digest: str | None, out: Path,
                  keep: set[str] | frozenset[str] = frozenset(), record: dict | None = None
                  ) -> list[str]:
    """Remove the export files an earlier run recorded for this scene (`record`, else read
    from `exports_record`) from another packing or with other settings, unchanged since
    written, that were not made again (`keep`): beside a packing made since, they printed
    one that no longer exists. A record left describing nothing is removed too. Files
    changed since they were written are left, and said so. Returns what was removed or
    left, with why."""
    if record is None:
        record = _read_record(exports_record(out, spec))
    if not record or _current(record, digest, spec):
        return []
    notes = _remove_recorded(out, record["files"], keep,
                             "made from an earlier packing or settings",
                             "an export of an earlier packing or settings, not made again")
    if not spec.export and not any(note.startswith(("left", "could not")) for note in notes):
        try:  # it describes nothing now
            exports_record(out, spec).unlink()
        except OSError:
            pass
    return notes


def _settings(spec: SceneSpec) -> dict:
    """The export settings a record keeps, as the scene asks for them."""
    return {"mode": spec.export_mode, "shell": spec.export_shell}


def _current(record: dict, digest: str | None, spec: SceneSpec) -> bool:
    """Whether `record` describes exports of the packing `digest` with the scene's settings."""
    return record.get("packing") == digest and record.get("settings") == _settings(spec)


def _stale_export(path: Path, record: dict, made: dict, settings: dict,
                  digest: str | None) -> str:
    """Why the export file at `path` must be made again ("" if its record vouches for it)."""
    if not path.is_file():
        return "missing"
    if not record:
        return (f"no record of how it was made ({path.stem}.exports.json is missing or "
                "unreadable, or an older jampacked exported it)")
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
