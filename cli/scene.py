"""What ``jampacked pack`` packs: the scene resolved from its arguments (the bundled default
scene, the types and their shares, the container) and the checks on input and output paths.

Lengths are in container units (millimetres when the result is meant for printing).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from jampacked.cli.args import UsageError
from jampacked.core.atomic import missing_folder, refusal_advice, write_refusal
from jampacked.core.errors import InputError
from jampacked.core.mesh_files import MESH_EXTENSIONS
from jampacked.core.meshes import parse_box_spec
from jampacked.core.packing import is_spec
from jampacked.core.packing_types import distinct_names

#: the bundled default scene (inside the installed jampacked.core package)
DEFAULT_SCENE = ("data", "default_scene")
DEFAULT_CONTAINER = "spot.obj"
DEFAULT_TYPES = ("011_banana.obj", "012_strawberry.obj", "014_lemon.obj", "015_peach.obj",
                 "017_orange.obj")
DEFAULT_CONTAINER_SIZE = 150.0  # Spot's largest extent, container units (mm)
DEFAULT_TYPE_SCALE = 300.0  # the YCB fruit files are in metres


@dataclass
class Scene:
    """What `pack()` is called with, resolved from the command line."""

    container: str
    types: list[str]
    shares: list[float] | None
    names: list[str] | None
    container_size: float | None
    type_scale: float
    notes: list[str] = field(default_factory=list)  # said before packing (warnings)


_SHARE_RE = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(%?)\s*$")


def parse_type_arg(text: str) -> tuple[str, float | None]:
    """Split ``FILE[=SHARE]`` into the path and the share as a fraction (None if absent).

    A SHARE is a fraction (``0.4``), a weight (``2``) or a percent (``40%``). A path that
    exists as given is taken whole, even if it holds '='. Raises UsageError.
    """
    if not text:
        raise UsageError("--type needs a mesh file, e.g. --type apple.obj=40%")
    if os.path.isfile(text) or "=" not in text:
        return text, None
    path, share_text = text.rsplit("=", 1)
    if not path:
        raise UsageError(f"--type {text}: the mesh file is missing before '='; "
                         "write --type FILE=SHARE, e.g. --type apple.obj=40%")
    m = _SHARE_RE.match(share_text)
    if not m:
        raise UsageError(f"--type {text}: share {share_text!r} is not a number; write a "
                         "fraction (0.4) or a percent (40%)")
    value = float(m.group(1))
    if m.group(2):
        if value > 100:
            raise UsageError(f"--type {text}: share {share_text} is over 100%")
        value /= 100.0
    if not math.isfinite(value) or value <= 0:
        raise UsageError(f"--type {text}: share {share_text} must be greater than 0 "
                         "(leave the type out to not pack it)")
    return path, value


def resolve_shares(shares: Sequence[float | None], labels: Sequence[str]) -> list[float] | None:
    """Target shares for every type from the optional ones given.

    All missing: None (uniform). All given: returned as they are (pack() normalises them).
    Some missing: the given ones are fractions that must add up to less than 1, and the
    missing ones split the rest equally. Raises UsageError.
    """
    given = [s for s in shares if s is not None]
    if not given:
        return None
    if len(given) == len(shares):
        return [float(s) for s in shares]
    total = float(sum(given))
    missing = [lab for lab, s in zip(labels, shares, strict=True) if s is None]
    if total >= 1.0 - 1e-9:
        raise UsageError(
            f"the shares given add up to {_percent(total)}, which leaves nothing for "
            f"{', '.join(missing)}: give shares that add up to less than 100%, or give every "
            "type a share")
    rest = (1.0 - total) / len(missing)
    return [float(s) if s is not None else rest for s in shares]


def shares_note(shares: Sequence[float] | None, labels: Sequence[str]) -> str | None:
    """A note when every type's share is a fraction or a percent (none a weight above 1)
    and they do not add up to 100% (within half a point): they are then read as
    proportions, which a typo (40% + 40% + 40%) would silently change. labels: the types'
    names."""
    if not shares or any(s > 1.0 for s in shares):
        return None
    total = float(sum(shares))
    if abs(total - 1.0) <= 0.005:
        return None
    # one decimal where a whole percent would not add up (50% and 30%: 62.5% and 37.5%)
    scaled = ", ".join(f"{lab} {f'{100 * s / total:.1f}'.removesuffix('.0')}%"
                       for lab, s in zip(labels, shares, strict=True))
    return (f"the shares add up to {_percent(total)}, not 100%; they are taken as proportions: "
            f"{scaled}")


def _percent(fraction: float) -> str:
    """A total of shares in percent: whole above 10%, two digits below (0.3% + 0.2% read
    as 0%)."""
    v = 100.0 * fraction
    return f"{v:.0f}%" if v >= 9.5 else f"{v:.2g}%"


def check_mesh_file(path: str, role: str) -> None:
    """Raise UsageError unless ``path`` is an existing file (``role``: container/object)."""
    if not os.path.exists(path):
        raise UsageError(f"{role} mesh file '{path}' does not exist; check the path")
    if os.path.isdir(path):
        raise UsageError(f"{role} mesh file '{path}' is a folder; give a mesh file"
                         + (" (one --type per file: --type fruit/apple.obj --type "
                            "fruit/pear.obj)" if role == "object" else ""))
    if not os.path.isfile(path):
        raise UsageError(f"{role} mesh file '{path}' is not a file")


def require_png(path: str, option: str, what: str) -> None:
    """Raise UsageError unless ``path`` (given to ``option``, a ``what`` image) is a .png
    name: no mesh or JSON the command reads or writes is one."""
    if Path(path).suffix.lower() != ".png":
        raise UsageError(f"{option} {path}: the {what} is a PNG image; give it a .png name, "
                         f"e.g. {what}.png")


def check_output(path: str, option: str, inputs: Sequence[str],
                 what: str = "input mesh") -> None:
    """Raise UsageError unless ``path`` can be written by ``option``: its folder exists and
    takes new files, it is no folder and none of ``inputs`` (named ``what`` in the
    message)."""
    if not path.strip():
        raise UsageError(f"{option} is empty: give a file name")
    out = os.path.abspath(path)
    folder = os.path.dirname(out)
    missing = missing_folder(folder)
    if missing:
        raise UsageError(f"{option} {path}: {missing}")
    if os.path.isdir(out):
        raise UsageError(f"{option} {path} is a folder; give a file name")
    refused = write_refusal(folder)
    if refused:
        raise UsageError(f"{option} {path}: cannot write in folder {folder} ({refused}). "
                         f"{refusal_advice(folder)}, or give another output file")
    for src in inputs:
        with contextlib.suppress(OSError):
            if os.path.exists(out) and os.path.samefile(out, src):
                raise UsageError(f"{option} {path} is the {what} {src}; choose another "
                                 "output file")


def default_scene(stack: contextlib.ExitStack) -> tuple[str, list[str], list[str]]:
    """Real file paths of the bundled default scene (container, types, type names)."""
    folder = resources.files("jampacked.core")
    for part in DEFAULT_SCENE:
        folder = folder.joinpath(part)

    def real(name: str) -> str:
        return os.fspath(stack.enter_context(resources.as_file(folder.joinpath(name))))

    container = real(DEFAULT_CONTAINER)
    types = [real(n) for n in DEFAULT_TYPES]
    names = [re.sub(r"^\d+_", "", Path(n).stem) for n in DEFAULT_TYPES]
    return container, types, names


def resolve_scene(args: argparse.Namespace, stack: contextlib.ExitStack) -> Scene:
    """Check the pack arguments (files exist, shares, box spec) and apply the default scene."""
    container = args.container
    container_size = args.container_size
    type_scale = args.type_scale
    names = None
    parsed = [parse_type_arg(t) for t in args.types]
    if container.strip().lower() == "default" and not os.path.exists(container):
        container, default_types, default_names = default_scene(stack)
        if container_size is None:
            container_size = DEFAULT_CONTAINER_SIZE
        if not parsed:
            parsed = [(p, None) for p in default_types]
            names = default_names
            if type_scale is None:
                type_scale = DEFAULT_TYPE_SCALE
    elif os.path.isfile(container):
        pass
    elif is_spec(container):
        try:
            box = parse_box_spec(container)
        except InputError as exc:
            raise UsageError(str(exc)) from None
        if box is None:
            raise UsageError(f"container {container!r} is neither a mesh file nor a known "
                             "spec: use a mesh file, box:WIDTHxDEPTHxHEIGHT or 'default'")
    else:
        check_mesh_file(container, "container")
    if not parsed:
        raise UsageError("no object types: give at least one --type FILE[=SHARE] "
                         "(or use the container 'default' for the bundled scene)")
    for path, _ in parsed:
        check_mesh_file(path, "object")
    paths = [p for p, _ in parsed]
    shares = resolve_shares([s for _, s in parsed], paths)
    inputs = paths + ([container] if os.path.isfile(container) else [])
    check_output(args.output, "-o", inputs)
    ext = Path(args.output).suffix.lower().lstrip(".")
    if ext in MESH_EXTENSIONS:
        raise UsageError(f"-o {args.output}: pack writes the packing, a JSON file, not a "
                         f"mesh; give a .json name, then write the {ext.upper()} with "
                         f"'jampacked export PACKING.json -o {Path(args.output).name}'")
    if args.preview:
        check_output(args.preview, "--preview", inputs)
        require_png(args.preview, "--preview", "preview")
        if os.path.abspath(args.preview) == os.path.abspath(args.output):
            raise UsageError("--preview and -o name the same file; give the preview its own "
                             "name, e.g. preview.png")
    labels = names or distinct_names([Path(p).stem for p in paths])
    notes = [n for n in (twice_note(paths, labels), shares_note(shares, labels)) if n]
    return Scene(container=container, types=paths, shares=shares, names=names,
                 container_size=container_size,
                 type_scale=1.0 if type_scale is None else type_scale,
                 notes=notes)


def twice_note(paths: Sequence[str], labels: Sequence[str]) -> str | None:
    """A note when one mesh file is given as more than one type (the types' files and
    names): that packs as that many types, each with its own share and spread (two colours
    of one bead), which a repeated --type by mistake would silently do."""
    seen: dict[object, list[int]] = {}
    for i, p in enumerate(paths):
        try:  # the file itself: through links, hard links and case-blind volumes
            st = os.stat(p)
            key: object = (st.st_dev, st.st_ino)
        except OSError:
            key = os.path.normcase(os.path.realpath(p))
        seen.setdefault(key, []).append(i)
    twice = [idx for idx in seen.values() if len(idx) > 1]
    if not twice:
        return None
    said = "; ".join(f"{' and '.join(dict.fromkeys(paths[i] for i in idx))} as "
                     f"{', '.join(labels[i] for i in idx)}" for idx in twice)
    return (f"a mesh file is given more than once: {said}. Each copy packs as a type of its "
            "own, with its own share and spread (as for two colours of one object); to pack "
            "it as one type, give it once (with the sum of their shares, if given).")
