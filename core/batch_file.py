"""Batch files: the scenes of `jampacked batch`, written by hand in TOML.

```toml
[defaults]                  # optional: every scene's settings unless it sets its own
fidelity = "low"

[[scene]]
name = "jar"                # optional; the packing files are named <name>-...-s<seed>.json
containers = ["jar.stl", "box:40x40x45"]   # or container = "jar.stl"
container_size = 120        # optional (container units)
type_sets = [["apple.obj", "lemon.obj"], ["plum.obj"]]   # or types = ["apple.obj", ...]
shares = [0.6, 0.4]         # optional, one per type (with `types` only)
seeds = [1, 2, 3]           # or seed = 1
clearance = 0.4             # optional, as `jampacked pack`: type_scale, fidelity,
time_budget = 30            # time_budget, attempts, mix_tolerance
export = ["3mf", "stl"]     # optional: also export each packing (<id>.3mf, <id>.stl)
export_mode = "parts"       # optional: union, connect (default) or parts
export_shell = 2.0          # optional: a container shell this thick
```

Each scene expands to containers x object sets x seeds; each gets an id that names its
packing file. Mesh paths are relative to the batch file's folder. Errors name the scene (its
number and line) and the key, say what is wrong and how to fix it.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import InputError
from .fidelity import PRESETS
from .meshes import parse_box_spec

#: settings a scene (or [defaults]) may give, besides its meshes and seeds
SETTINGS = ("container_size", "type_scale", "clearance", "fidelity", "time_budget",
            "attempts", "mix_tolerance", "shares", "export", "export_mode", "export_shell")
EXPORT_FORMATS = ("3mf", "stl", "obj", "ply")
EXPORT_MODES = ("union", "connect", "parts")
SCENE_KEYS = ("name", "container", "containers", "types", "type_sets", "seed", "seeds",
              *SETTINGS)
_ID_RE = re.compile(r"[^A-Za-z0-9_.-]+")
#: the longest scene id: its files' names (the exports' record, the temporary name it is
#: written under: 27 characters more) stay within the 255 bytes file systems allow
MAX_ID = 200


@dataclass(frozen=True)
class SceneSpec:
    """One packing of a batch: meshes (absolute paths or a box spec), seed and settings as
    `pack()` takes them (container units, seconds)."""

    id: str
    container: str
    types: tuple[str, ...]
    seed: int
    shares: tuple[float, ...] | None = None
    container_size: float | None = None
    type_scale: float = 1.0
    clearance: float = 0.0
    fidelity: str = "auto"
    time_budget: float | None = None
    attempts: int | None = None
    mix_tolerance: float | None = None
    export: tuple[str, ...] = ()  # file formats to export the packing to
    export_mode: str = "connect"
    export_shell: float | None = None
    where: str = ""  # "scene 2 (line 7)" for messages


def read_batch(path: str | os.PathLike) -> list[SceneSpec]:
    """The scenes a batch file lists, expanded and checked; raises InputError naming the
    file, the scene and the key of the first problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")  # editors on Windows may add a BOM
    except OSError as exc:
        raise InputError(f"cannot read batch file {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise InputError(f"batch file {path} is not UTF-8 text (TOML).") from None
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"batch file {path} is not valid TOML: {exc}. See 'jampacked "
                         "batch --help' for an example.") from None
    unknown = sorted(set(doc) - {"defaults", "scene"})
    if unknown:
        raise InputError(f"batch file {path}: unknown top-level key {unknown[0]!r}; a batch "
                         "file has [defaults] and [[scene]] tables only.")
    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise InputError(f"batch file {path}: 'defaults' must be a table ([defaults]).")
    for key in defaults:
        if key not in SETTINGS:
            raise InputError(f"batch file {path}, [defaults]: unknown key {key!r}; known: "
                             f"{', '.join(SETTINGS)}.")
    scenes = doc.get("scene")
    if isinstance(scenes, dict):  # [scene], one bracket: a single table, not a list of them
        raise InputError(f"batch file {path}: a scene is written [[scene]], with two "
                         "brackets on each side (a list of scenes); [scene] makes one table "
                         "of them all.")
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, dict)
                                                            for s in scenes):
        raise InputError(f"batch file {path} lists no scenes: add at least one [[scene]] "
                         "table with a container, types and a seed.")
    lines = _scene_lines(text)
    base = path.resolve().parent
    out: list[SceneSpec] = []
    seen: dict[str, tuple[str, str]] = {}
    for k, scene in enumerate(scenes):
        where = f"scene {k + 1}" + (f" (line {lines[k]})" if k < len(lines) else "")
        for key in scene:
            if key not in SCENE_KEYS:
                at = _key_line(text, lines, k, key)
                raise InputError(f"batch file {path}, {where}: unknown key {key!r}"
                                 f"{f' on line {at}' if at else ''}; known: "
                                 f"{', '.join(SCENE_KEYS)}.")
        for spec in _expand(scene, defaults, base, f"batch file {path}, {where}", k):
            # case folded: "A" and "a" name one file on macOS and Windows
            other = seen.get(spec.id.casefold())
            if other is not None:
                raise InputError(f"batch file {path}, {where}: {_same_id(spec.id, *other)}")
            seen[spec.id.casefold()] = (spec.id, where)
            out.append(spec)
    return out


def _same_id(new: str, old: str, where: str) -> str:
    """Why scene id `new` may not follow `old` (made by `where`), and how to fix it."""
    if new != old:
        return (f"scene id {new!r} differs from {old!r} of {where} only in case, and they "
                "would write one file on macOS and Windows; give the scenes different "
                "names.")
    return (f"scene id {new!r} is also made by {where}; give the scenes different names "
            "(a name keeps its letters, digits, '_', '.' and '-', and any other characters "
            "become '_', so 'a b' and 'a_b' are one name).")


def _scene_lines(text: str) -> list[int]:
    """The line number of each [[scene]] header, in order."""
    return [i + 1 for i, line in enumerate(text.splitlines())
            if re.match(r"\s*\[\[\s*scene\s*\]\]", line)]


def _key_line(text: str, headers: list[int], k: int, key: str) -> int | None:
    """The line of `key` in scene k's table (between its header and the next), or None."""
    if k >= len(headers):
        return None
    rows = text.splitlines()
    end = headers[k + 1] - 1 if k + 1 < len(headers) else len(rows)
    pattern = re.compile(rf"\s*(?:{re.escape(key)}|\"{re.escape(key)}\"|'{re.escape(key)}')\s*=")
    return next((i + 1 for i in range(headers[k], end) if pattern.match(rows[i])), None)


def _expand(scene: dict, defaults: dict, base: Path, where: str, k: int) -> list[SceneSpec]:
    merged = {**defaults, **scene}
    name = merged.get("name", f"scene{k + 1}")
    if not isinstance(name, str) or not _file_name(name):
        raise InputError(f"{where}: 'name' must be a string with a letter or digit, got "
                         f"{name!r}.")
    name = _file_name(name)
    containers = _one_or_many(merged, "container", "containers", where, str)
    containers = [_mesh(c, base, f"{where}, container", container=True) for c in containers]
    sets = _type_sets(merged, where)
    sets = [tuple(_mesh(t, base, f"{where}, types") for t in s) for s in sets]
    seeds = _one_or_many(merged, "seed", "seeds", where, int)
    for i, s in enumerate(seeds):
        if s < 0:
            raise InputError(f"{where}: seeds must be whole numbers >= 0, got {s}.")
        if s in seeds[:i]:
            raise InputError(f"{where}: seed {s} is listed twice in 'seeds'; list each seed "
                             "once.")
    settings = _settings(merged, where)
    _check_export(settings, where)
    shares = settings.pop("shares", None)
    if shares is not None and len(sets) == 1 and len(shares) != len(sets[0]):
        raise InputError(f"{where}: 'shares' has {len(shares)} values for "
                         f"{len(sets[0])} types; give one share per type.")
    if shares is not None and len(sets) > 1:
        raise InputError(f"{where}: 'shares' goes with 'types' (one object set), not with "
                         "'type_sets'; give each set its own [[scene]].")
    out = []
    for ci, container in enumerate(containers):
        for ti, types in enumerate(sets):
            for seed in seeds:
                parts = [name] + ([f"c{ci + 1}"] if len(containers) > 1 else []) + (
                    [f"t{ti + 1}"] if len(sets) > 1 else []) + [f"s{seed}"]
                scene_id = "-".join(parts)
                if len(scene_id) > MAX_ID:
                    most = MAX_ID - (len(scene_id) - len(name))
                    if most < 1:  # the seed alone is too long
                        raise InputError(f"{where}: seed {seed} is too long for a file name "
                                         f"({len(str(seed))} digits); give seeds of at most "
                                         f"{MAX_ID - len(scene_id) + len(str(seed))} "
                                         "digits.")
                    raise InputError(f"{where}: 'name' is too long for a file name "
                                     f"({len(name)} characters); give a name of at most "
                                     f"{most}.")
                out.append(SceneSpec(id=scene_id, container=container,
                                     types=types, seed=seed, shares=shares, where=where,
                                     **settings))
    return out


def _file_name(name: str) -> str:
    """`name` as the start of a file name: runs of characters other than letters, digits,
    '_', '.' and '-' become '_', and leading '.', '-' and '_' go (a leading dot would hide
    the files, a leading dash reads as a command-line option)."""
    return _ID_RE.sub("_", name).lstrip("._-")


def _one_or_many(d: dict, one: str, many: str, where: str, kind: type) -> list:
    if one in d and many in d:
        raise InputError(f"{where}: give {one!r} or {many!r}, not both.")
    if one in d:
        values = [d[one]]
        key = one
    elif many in d:
        values = d[many]
        key = many
        if not isinstance(values, list) or not values:
            raise InputError(f"{where}: {many!r} must be a non-empty list, got {values!r}.")
    else:
        raise InputError(f"{where}: {one!r} (or {many!r}, a list) is missing.")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, kind):
            what = "a string" if kind is str else "a whole number"
            raise InputError(f"{where}: every value of {key!r} must be {what}, got {v!r}.")
    return list(values)


def _type_sets(d: dict, where: str) -> list[list[str]]:
    if "types" in d and "type_sets" in d:
        raise InputError(f"{where}: give 'types' or 'type_sets', not both.")
    if "types" in d:
        sets, key = [d["types"]], "types"
    elif "type_sets" in d:
        sets, key = d["type_sets"], "type_sets"
        if not isinstance(sets, list) or not sets:
            raise InputError(f"{where}: 'type_sets' must be a non-empty list of lists of "
                             "mesh files.")
    else:
        raise InputError(f"{where}: 'types' (a list of object mesh files) is missing.")
    for s in sets:
        if not isinstance(s, list) or not s or not all(isinstance(t, str) for t in s):
            raise InputError(f"{where}: {key!r} must hold non-empty lists of mesh files "
                             f"(strings), got {s!r}.")
    return sets


def _mesh(text: str, base: Path, where: str, container: bool = False) -> str:
    if container:
        try:
            box = parse_box_spec(text)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        if box is not None:
            return text
    p = Path(text).expanduser()
    p = p if p.is_absolute() else base / p
    try:
        found = p.is_file()
    except OSError as exc:  # a name too long for the file system
        raise InputError(f"{where}: mesh file {_shorten(text)!r} cannot be looked up: "
                         f"{exc.strerror or exc}. Give a shorter path.") from None
    if not found and p.is_dir():
        raise InputError(f"{where}: {text!r} is a folder ({p}), not a mesh file: name each "
                         "mesh file in it (e.g. types = [\"m/lemon.obj\", \"m/pear.obj\"]).")
    if not found:
        raise InputError(f"{where}: mesh file {text!r} not found (looked for {p}); paths "
                         "are relative to the batch file's folder.")
    return str(p)


def _settings(d: dict, where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key in SETTINGS:
        if key not in d:
            continue
        v = d[key]
        if key == "fidelity":
            if v not in ("auto", *PRESETS):
                raise InputError(f"{where}: 'fidelity' must be auto, low, medium or high, "
                                 f"got {v!r}.")
        elif key == "attempts":
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise InputError(f"{where}: 'attempts' must be a whole number >= 1, got {v!r}.")
        elif key == "export":
            if isinstance(v, str):
                v = [v]
            if not isinstance(v, list) or not all(x in EXPORT_FORMATS for x in v):
                raise InputError(f"{where}: 'export' must be a list of formats from "
                                 f"{', '.join(EXPORT_FORMATS)}, got {v!r}.")
            twice = next((x for i, x in enumerate(v) if x in v[:i]), None)
            if twice is not None:
                raise InputError(f"{where}: 'export' lists {twice!r} twice; list each format "
                                 "once.")
            v = tuple(v)
        elif key == "export_mode":
            if v not in EXPORT_MODES:
                raise InputError(f"{where}: 'export_mode' must be one of "
                                 f"{', '.join(EXPORT_MODES)}, got {v!r}.")
        elif key == "shares":
            if not isinstance(v, list) or not all(_real(x) and x >= 0 for x in v) \
                    or not sum(v) > 0:
                raise InputError(f"{where}: 'shares' must be a list of numbers >= 0 with a "
                                 f"positive sum, got {v!r}.")
            v = tuple(float(x) for x in v)
        else:
            low = 0.0 if key in ("clearance", "mix_tolerance") else None
            ok = _real(v) and (v >= 0 if low is not None else v > 0)
            if key == "mix_tolerance":
                ok = ok and v <= 1
            if not ok:
                rule = ("from 0 to 1" if key == "mix_tolerance" else
                        ">= 0" if low is not None else "> 0")
                raise InputError(f"{where}: {key!r} must be a finite number {rule}, got {v!r}.")
            v = float(v)
        out[key] = v
    return out


def _check_export(settings: dict[str, Any], where: str) -> None:
    """Refuse, in the batch file's words, an export its packings cannot give: parts need a
    clearance (objects that touch fuse into one part) and have no shell (it would trap
    them). Checked when the file is read, so no scene is packed for an export that fails."""
    if not settings.get("export") or settings.get("export_mode") != "parts":
        return
    if settings.get("clearance", 0.0) <= 0:
        raise InputError(
            f"{where}: export_mode = \"parts\" needs a gap between the objects, but "
            "'clearance' is 0 (touching objects would print fused). Give e.g. clearance = "
            "0.2 in this scene (or in [defaults]), or export_mode = \"union\" or "
            "\"connect\".")
    if settings.get("export_shell") is not None:
        raise InputError(
            f"{where}: export_mode = \"parts\" writes the objects only, and 'export_shell' "
            "would trap them; drop export_shell, or use export_mode = \"union\" or "
            "\"connect\".")


def _real(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _shorten(text: str, most: int = 80) -> str:
    return text if len(text) <= most else text[: most - 3] + "..."
