"""The ``jampacked`` command line: ``jampacked pack ...``, ``info ...`` and ``validate ...``.

A thin front end over :func:`jampacked.core.api.pack` and the packing JSON file. Lengths are
in container units (millimetres when the result is meant for printing).

Exit status: 0 success; 1 the engine refused (a :class:`JampackedError`: unusable mesh, no
object fits, unreadable packing file...) or ``info`` found a missing/changed source file;
2 bad command-line arguments (missing file, bad share, bad box spec...); 130 interrupted
(after Ctrl-C during packing the best certified packing so far is still saved).
``validate``: 0 every file is watertight, 1 some file is not, 2 a file is missing or unreadable.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import math
import os
import re
import signal
import sys
import textwrap
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from jampacked.cli.export_cmd import add_export_parser
from jampacked.core.api import PackParams, pack
from jampacked.core.errors import InputError, JampackedError
from jampacked.core.meshes import parse_box_spec
from jampacked.core.packing import Packing, is_spec
from jampacked.core.packing_json import load_packing, save_packing, verify_sources

if TYPE_CHECKING:  # imported when needed: validation pulls in numba kernels
    from jampacked.export.validate import ValidationReport

#: exit status for bad command-line arguments (argparse uses the same)
EXIT_USAGE = 2
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130

#: the bundled default scene (inside the installed jampacked.core package)
DEFAULT_SCENE = ("data", "default_scene")
DEFAULT_CONTAINER = "spot.obj"
DEFAULT_TYPES = ("011_banana.obj", "012_strawberry.obj", "014_lemon.obj", "015_peach.obj",
                 "017_orange.obj")
DEFAULT_CONTAINER_SIZE = 150.0  # Spot's largest extent, container units (mm)
DEFAULT_TYPE_SCALE = 300.0  # the YCB fruit files are in metres


class UsageError(Exception):
    """A bad command-line argument: reported on one line, exit status 2."""


# --------------------------------------------------------------------------- parser

_FORMATTER = argparse.RawDescriptionHelpFormatter


def _fill(text: str) -> str:
    """Wrap a description (the raw formatter keeps the epilogs' own line breaks)."""
    return textwrap.fill(text, width=88)

_MAIN_EPILOG = """\
examples:
  jampacked pack default -o out/packing.json --preview out/preview.png
  jampacked pack vase.stl --container-size 120 --type apple.obj=40% \\
      --type lemon.obj=30% --type plum.obj -o packing.json
  jampacked pack box:40x40x45 --type cube.stl --type ball.stl --clearance 0.4 \\
      --time-budget 60 -o packing.json
  jampacked export out/packing.json --mode connect --shell 2 --up +y \\
      --open-plane +y@0.55 --drain 3 -o out/spot.3mf -o out/spot.stl
  jampacked info packing.json
  jampacked validate out/spot.3mf

Run 'jampacked COMMAND --help' for the options of a command.
Lengths are in container units: millimetres when the result is meant for printing.
"""

_PACK_EPILOG = """\
shares:
  --type FILE=SHARE gives a type's target share by count, as a fraction (0.4) or a
  percent (40%%). Types without a share split what is left equally; with no shares at all
  every type gets the same share. When every type has a share, the shares are normalised,
  so --type a.stl=2 --type b.stl=1 means two a's for each b.

units:
  The container's units are the scene's units (millimetres for printing).
  --container-size scales the container so its largest bounding-box side is that long;
  --type-scale multiplies the object files' coordinates (1000 turns metres into mm).

examples:
  jampacked pack default -o out/packing.json --preview out/preview.png
      Spot the cow (150 mm) filled with five kinds of fruit.
  jampacked pack vase.stl --container-size 120 --type apple.obj=40%% \\
      --type lemon.obj=30%% --type plum.obj -o packing.json
      40%% apples, 30%% lemons, 30%% plums in a vase 120 mm tall (or wide).
  jampacked pack box:40x40x45 --type cube.stl --type ball.stl --clearance 0.4 \\
      --time-budget 60 --seed 7 -o packing.json --preview preview.png
      Equal shares in a 40 x 40 x 45 mm box, at least 0.4 mm between parts.

Ctrl-C stops early: the best certified packing found so far is saved (exit status 130);
press Ctrl-C twice to abort without saving. Exit status: 0 done, 1 the engine refused
(the message says why and how to fix it), 2 bad arguments.
"""

_INFO_EPILOG = """\
examples:
  jampacked info packing.json

Exit status: 0 all good, 1 the file cannot be read or a mesh file it names is missing or
has changed since the packing was made.
"""


def _positive_float(what: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a number, got {text!r}") from None
        if not math.isfinite(value) or value <= 0:
            raise argparse.ArgumentTypeError(f"{what} must be greater than 0, got {text!r}")
        return value

    return parse


def _non_negative_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text!r}")
    return value


def _fraction(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number from 0 to 1, got {text!r}") from None
    if not math.isfinite(value) or not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be from 0 to 1, got {text!r}")
    return value


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text!r}")
    return value


def _add_pack_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "pack",
        help="pack objects into a container and save the packing (JSON)",
        description=_fill(
            "Fill a container mesh as densely as possible with copies of the given object "
            "types, keeping their target shares and spreading each type evenly. Every "
            "packing is certified on the real meshes (no overlap, nothing through the wall, "
            "the clearance kept) before it is saved."
        ),
        epilog=_PACK_EPILOG,
        formatter_class=_FORMATTER,
    )
    p.add_argument(
        "container", metavar="CONTAINER",
        help="container mesh file (STL, OBJ, PLY, OFF, GLB, ...); 'box:AxBxC' for a box "
             "centred at the origin (container units); or 'default' for the bundled scene "
             f"(Spot the cow at {DEFAULT_CONTAINER_SIZE:g} mm with five kinds of fruit)")
    p.add_argument(
        "-t", "--type", dest="types", metavar="FILE[=SHARE]", action="append", default=[],
        help="an object type: its mesh file and optional target share by count (0.4 or "
             "40%%). Repeat for each type. Required unless CONTAINER is 'default' "
             "(giving --type there replaces the fruit)")
    p.add_argument(
        "-o", "--output", required=True, metavar="PACKING.json",
        help="where to write the packing (JSON; written atomically)")
    p.add_argument(
        "--preview", metavar="PREVIEW.png",
        help="also write a PNG of cross-sections at 25%%, 50%% and 75%% of the container's "
             "height, objects coloured by type")
    p.add_argument(
        "--container-size", type=_positive_float("--container-size"), metavar="MM",
        help="scale the container so its largest bounding-box side is MM container units "
             f"(default: the file's own size; {DEFAULT_CONTAINER_SIZE:g} for 'default')")
    p.add_argument(
        "--type-scale", type=_positive_float("--type-scale"), metavar="S",
        help="multiply every object file's coordinates by S, e.g. 1000 for files in metres "
             f"(default: 1; {DEFAULT_TYPE_SCALE:g} for 'default', whose fruit are in metres)")
    p.add_argument(
        "--clearance", type=_non_negative_float, default=0.0, metavar="MM",
        help="minimum gap between objects and to the container wall, in container units; "
             "use about 0.3-0.5 mm to print objects as separate parts (default: 0, touching "
             "allowed)")
    p.add_argument(
        "--mix-tolerance", type=_fraction, metavar="TVD",
        help="how far the type mix may drift from the shares (total variation distance, 0 "
             "to 1) for the late passes to add an object to a small hole; the types a mix "
             "lacks late are often big ones that no longer fit, so a tight mix can leave "
             f"holes unfilled (default: {PackParams().extra_max_tvd:g}; 0 keeps the mix as "
             "close as the count allows)")
    p.add_argument(
        "--seed", type=_seed, default=0, metavar="N",
        help="random seed; the same inputs and seed give the same packing (default: 0)")
    p.add_argument(
        "--fidelity", choices=("auto", "low", "medium", "high"), default="auto",
        help="how closely the engine models object shapes while packing: low is fastest, "
             "high packs tightest; auto chooses from the scene: fewer spheres per object when "
             "thousands are expected, finer grids for elongated objects, a small clearance "
             "or a tight container (default: auto; the summary says what it chose). "
             "Certification always uses the exact meshes")
    p.add_argument(
        "--time-budget", type=_positive_float("--time-budget"), metavar="S",
        help="stop placing objects after S seconds and certify what is there (default: no "
             "limit; Ctrl-C also stops early)")
    p.add_argument(
        "-q", "--quiet", action="store_true",
        help="no progress bar and no summary (errors and warnings are still printed)")
    p.set_defaults(run=_cmd_pack)


def _add_info_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info",
        help="summarise a saved packing and check its mesh files",
        description=_fill(
            "Print the summary of a saved packing (objects per type, density, type-share "
            "error, clumping, certification, timings) and check that the mesh files it "
            "names are present and unchanged (sha256)."
        ),
        epilog=_INFO_EPILOG,
        formatter_class=_FORMATTER,
    )
    p.add_argument("packing", metavar="PACKING.json", help="a packing written by 'jampacked pack'")
    p.set_defaults(run=_cmd_info)


_VALIDATE_EPILOG = """\
checks, per body (faces joined by edges):
  closed (every edge used by exactly two faces), 2-manifold edges and vertices,
  consistent winding, outward (a solid has volume > 0; a cavity inside a solid is wound
  inwards), no degenerate or duplicate faces, no self-intersections (float64
  triangle-triangle tests on all nearby face pairs; touching counts), and no bodies that
  intersect, touch or sit inside another solid. The file is read as written: only
  vertices at identical positions are merged (as a slicer reads an STL); nothing is
  repaired. Offending face, edge and vertex indices are in the --json output.

examples:
  jampacked validate out/fruit.stl
  jampacked validate parts.3mf shell.obj --json > report.json

Exit status: 0 every file passes, 1 some file fails, 2 a file is missing or unreadable.
"""


def _add_validate_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "validate",
        help="check that mesh files are watertight and printable",
        description=_fill(
            "Read each mesh file as written and check, per body, that it is a closed, "
            "2-manifold, consistently and outward wound solid without degenerate or "
            "duplicate faces or self-intersections; print a table per file and a PASS/FAIL "
            "line."
        ),
        epilog=_VALIDATE_EPILOG,
        formatter_class=_FORMATTER,
    )
    p.add_argument("files", metavar="FILE", nargs="+",
                   help="mesh files (STL, OBJ, PLY, 3MF, OFF, GLB, ...)")
    p.add_argument("--json", action="store_true",
                   help="print one JSON document (reports with offending element indices) "
                        "instead of tables")
    p.add_argument("--no-manifold3d", dest="manifold3d", action="store_false",
                   help="skip the independent cross-check by manifold3d (about a third of "
                        "the time on large meshes; every other check still runs, the report "
                        "says 'skipped')")
    p.set_defaults(run=_cmd_validate)


#: subcommands, in the order of the help text
_COMMANDS = (_add_pack_parser, add_export_parser, _add_info_parser, _add_validate_parser)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``jampacked`` command."""
    parser = argparse.ArgumentParser(
        prog="jampacked",
        description=_fill(
            "Pack 3D objects densely into a container mesh: mixed types at target shares, "
            "no clumps of one type, every placement certified on the real meshes."
        ),
        epilog=_MAIN_EPILOG,
        formatter_class=_FORMATTER,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    parser.add_argument(
        "--debug", action="store_true",
        help="show full tracebacks and the engine's log messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    sub.required = True
    for add in _COMMANDS:
        add(sub)
    return parser


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return "unknown"
    try:
        return version("jampacked")
    except PackageNotFoundError:
        return "(not installed)"


# --------------------------------------------------------------------------- inputs


@dataclass
class Scene:
    """What `pack()` is called with, resolved from the command line."""

    container: str
    types: list[str]
    shares: list[float] | None
    names: list[str] | None
    container_size: float | None
    type_scale: float


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
            f"the shares given add up to {total:.0%}, which leaves nothing for "
            f"{', '.join(missing)}: give shares that add up to less than 100%, or give every "
            "type a share")
    rest = (1.0 - total) / len(missing)
    return [float(s) if s is not None else rest for s in shares]


def _check_mesh_file(path: str, role: str) -> None:
    if not os.path.exists(path):
        raise UsageError(f"{role} mesh file '{path}' does not exist; check the path")
    if not os.path.isfile(path):
        raise UsageError(f"{role} mesh file '{path}' is not a file")


def _check_output(path: str, option: str, inputs: Sequence[str]) -> None:
    out = os.path.abspath(path)
    folder = os.path.dirname(out)
    if not os.path.isdir(folder):
        raise UsageError(f"{option} {path}: folder {folder} does not exist; create it first")
    if os.path.isdir(out):
        raise UsageError(f"{option} {path} is a folder; give a file name")
    for src in inputs:
        with contextlib.suppress(OSError):
            if os.path.exists(out) and os.path.samefile(out, src):
                raise UsageError(f"{option} {path} is the input mesh {src}; choose another "
                                 "output file")


def _default_scene(stack: contextlib.ExitStack) -> tuple[str, list[str], list[str]]:
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
        container, default_types, default_names = _default_scene(stack)
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
        _check_mesh_file(container, "container")
    if not parsed:
        raise UsageError("no object types: give at least one --type FILE[=SHARE] "
                         "(or use the container 'default' for the bundled scene)")
    for path, _ in parsed:
        _check_mesh_file(path, "object")
    paths = [p for p, _ in parsed]
    shares = resolve_shares([s for _, s in parsed], paths)
    inputs = paths + ([container] if os.path.isfile(container) else [])
    _check_output(args.output, "-o", inputs)
    if args.preview:
        _check_output(args.preview, "--preview", inputs)
        if os.path.abspath(args.preview) == os.path.abspath(args.output):
            raise UsageError("--preview and -o name the same file; give the preview its own "
                             "name, e.g. preview.png")
    return Scene(container=container, types=paths, shares=shares, names=names,
                 container_size=container_size,
                 type_scale=1.0 if type_scale is None else type_scale)


# --------------------------------------------------------------------------- Ctrl-C


class CancelOnInterrupt:
    """While active, the first Ctrl-C (SIGINT) only sets `requested` (the engine's
    should_cancel), so packing stops and certifies what it has; a second Ctrl-C raises
    KeyboardInterrupt as usual. Does nothing outside the main thread."""

    def __init__(self) -> None:
        self.requested = False
        self._previous = None
        self._installed = False

    def __call__(self) -> bool:
        return self.requested

    def _handler(self, signum, frame) -> None:
        self.requested = True
        signal.signal(signal.SIGINT, self._restore())

    def _restore(self):
        return signal.default_int_handler if self._previous is None else self._previous

    def __enter__(self) -> CancelOnInterrupt:
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.getsignal(signal.SIGINT)
            signal.signal(signal.SIGINT, self._handler)
            self._installed = True
        return self

    def __exit__(self, *exc) -> None:
        if self._installed:
            signal.signal(signal.SIGINT, self._restore())
            self._installed = False


# --------------------------------------------------------------------------- commands


def _consoles() -> tuple[Console, Console]:
    """(stdout, stderr) consoles, made per call so redirected streams are honoured."""
    return Console(file=sys.stdout), Console(file=sys.stderr)


def _warn(err: Console, message: str) -> None:
    err.print(f"[yellow]warning:[/] {escape(message)}", highlight=False, soft_wrap=True)


def progress_bar(stack: contextlib.ExitStack, err: Console,
                 cancel: CancelOnInterrupt | None = None) -> Callable[[float, str], None]:
    """A rich progress bar on ``err`` for the life of ``stack``; returns the engine's
    ``progress(fraction, message)`` callback (noting a pending Ctrl-C when ``cancel``)."""
    bar = stack.enter_context(Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
        TimeElapsedColumn(), console=err, transient=False))
    task = bar.add_task("starting", total=1.0)

    def update(fraction: float, message: str) -> None:
        if cancel is not None and cancel.requested:
            message = f"{message} [yellow](stopping: Ctrl-C)[/]"
        bar.update(task, completed=min(max(fraction, 0.0), 1.0), description=message)

    return update


def _cmd_pack(args: argparse.Namespace) -> int:
    out, err = _consoles()
    with contextlib.ExitStack() as stack:
        scene = resolve_scene(args, stack)
        cancel = stack.enter_context(CancelOnInterrupt())
        progress_cb = None if args.quiet else progress_bar(stack, err, cancel)

        packing = pack(
            scene.container, scene.types, scene.shares, seed=args.seed,
            clearance=args.clearance, fidelity=args.fidelity, time_budget=args.time_budget,
            progress=progress_cb, should_cancel=cancel, container_size=scene.container_size,
            type_scale=scene.type_scale, names=scene.names,
            params=None if args.mix_tolerance is None
            else PackParams(extra_max_tvd=args.mix_tolerance))
    save_packing(packing, args.output)
    for w in packing.params.get("warnings") or []:
        _warn(err, w)
    if not args.quiet:
        print_summary(packing, out)
    if args.preview:
        from jampacked.cli.preview import write_preview

        write_preview(packing, args.preview)
    if not args.quiet:
        out.print(f"wrote {args.output}" + (f" and {args.preview}" if args.preview else ""),
                  highlight=False)
    if packing.params.get("stopped") == "cancelled":
        err.print(f"[yellow]interrupted:[/] saved the best certified packing found so far "
                  f"({packing.n} objects) to {escape(args.output)}", highlight=False)
        return EXIT_INTERRUPTED
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    out, err = _consoles()
    packing = load_packing(args.packing)
    print_summary(packing, out, title=f"packing {args.packing}")
    for w in packing.params.get("warnings") or []:
        _warn(err, w)
    problems = verify_sources(packing)
    n_files = len(packing.types) + (0 if is_spec(packing.container_path) else 1)
    if problems:
        for p in problems:
            err.print(f"[red]source:[/] {escape(p)}", highlight=False, soft_wrap=True)
        return EXIT_ERROR
    out.print(f"sources: all {n_files} mesh files present and unchanged", highlight=False)
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    from jampacked.export.validate import validate_file

    out, _ = _consoles()
    status = 0
    documents = []
    for path in args.files:
        try:
            report = validate_file(path, check_manifold3d=args.manifold3d)
        except JampackedError as exc:
            _error(exc)
            documents.append({"path": path, "passed": False, "error": " ".join(str(exc).split())})
            status = max(status, EXIT_USAGE)
            continue
        if not report.passed:
            status = max(status, EXIT_ERROR)
        if args.json:
            documents.append(report.as_dict())
        else:
            print_validation(report, out)
    if args.json:
        print(json.dumps({"format": "jampacked.validation-run", "version": 1,
                          "passed": status == 0, "exit_status": status, "files": documents},
                         indent=1, allow_nan=False))
    return status


#: bodies listed per file; failing bodies are listed first
MAX_BODY_ROWS = 20


def print_validation(report: ValidationReport, console: Console) -> None:
    """Print a validation report: a table of its bodies (failing ones first, at most
    MAX_BODY_ROWS), the whole-file checks and a PASS/FAIL line."""
    bodies = sorted(report.bodies, key=lambda b: (b.passed, b.index))
    table = Table(title=f"{escape(report.name)}: "
                        f"{len(report.bodies)} bod{'y' if len(report.bodies) == 1 else 'ies'}",
                  title_justify="left")
    table.add_column("body", justify="right")
    table.add_column("faces", justify="right")
    table.add_column("volume", justify="right")
    table.add_column("genus", justify="right")
    table.add_column("kind")
    table.add_column("result")
    for b in bodies[:MAX_BODY_ROWS]:
        result = ("[green]ok[/]" if b.passed
                  else "[red]" + escape("; ".join(b.problems)) + "[/]")
        table.add_row(str(b.index), str(b.faces), _volume(b.volume),
                      "-" if b.genus is None else str(b.genus), b.kind, result)
    rest = bodies[MAX_BODY_ROWS:]
    if rest:
        failing = sum(not b.passed for b in rest)
        table.add_row("...", str(sum(b.faces for b in rest)), _volume(sum(b.volume for b in rest)),
                      "", "", f"{len(rest)} more bodies" + (f", [red]{failing} failing[/]"
                                                            if failing else ", all ok"))
    console.print(table)
    lo, hi = report.bbox_min, report.bbox_max
    size = " x ".join(_num(b - a, "{:.4g}") for a, b in zip(lo, hi, strict=True))
    console.print(f"  volume {_volume(report.volume)} units³, bounding box {size} units, "
                  f"{report.n_faces} faces; self-intersections: {report.intersecting_pairs} "
                  f"face pairs; manifold3d: {report.manifold_status}", highlight=False)
    for problem in report.problems:
        console.print(f"  [red]{escape(problem)}[/]", highlight=False)
    style = "bold green" if report.passed else "bold red"
    console.print(f"[{style}]{escape(report.summary())}[/]", highlight=False, soft_wrap=True)


# --------------------------------------------------------------------------- summary


def _num(value, fmt: str = "{:.3g}", none: str = "-") -> str:
    if value is None:
        return none
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(v):
        return none
    return fmt.format(v)


def _pct(value, digits: int = 1) -> str:
    return _num(value, f"{{:.{digits}%}}")


def _seconds(value) -> str:
    return _num(value, "{:.1f} s")


def _volume(value) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "-"
    return f"{v:,.0f}" if 1e3 <= abs(v) < 1e15 else f"{v:.4g}"


def _container_label(packing: Packing) -> str:
    if is_spec(packing.container_path):
        return packing.container_path
    return Path(packing.container_path).name


def print_summary(packing: Packing, console: Console, title: str | None = None) -> None:
    """Print the summary tables of a packing: per type, quality and certificate, phases.

    Reads only what the packing holds (metrics, certificate, params, timings), so a packing
    loaded from JSON prints the same as one fresh from pack().
    """
    m = packing.metrics or {}
    cert = packing.certificate or {}
    params = packing.params or {}
    n_types = len(packing.types)
    counts = np.bincount(packing.type_index, minlength=n_types) if n_types else np.zeros(0)
    total = int(counts.sum())
    nni = list(m.get("nni_per_type") or [None] * n_types)
    nni += [None] * (n_types - len(nni))

    types = Table(title=title or "packing", title_justify="left", show_footer=True)
    types.add_column("type", footer="all")
    types.add_column("count", justify="right", footer=str(total))
    types.add_column("share", justify="right", footer="100%" if total else "-")
    types.add_column("target", justify="right", footer="100%")
    types.add_column("NNI", justify="right", footer=_num(m.get("nni_mean"), "{:.2f}"))
    for t, rec in enumerate(packing.types):
        share = counts[t] / total if total else None
        types.add_row(escape(rec.name), str(int(counts[t])), _pct(share), _pct(rec.share),
                      _num(nni[t], "{:.2f}"))
    console.print(types)

    clearance = float(cert.get("clearance", params.get("clearance", 0.0)) or 0.0)
    tol = cert.get("tol")
    summary = Table(show_header=False, title="quality", title_justify="left")
    summary.add_column("what", style="bold")
    summary.add_column("value")
    cs = escape(_container_label(packing))
    summary.add_row("container", f"{cs}, volume {_volume(packing.container_volume)} units³")
    summary.add_row("density", _pct(m.get("density")) + "  (object volume / container volume)")
    summary.add_row("TVD", _num(m.get("tvd"), "{:.3f}") + "  (type-share error: 0 = exact mix)")
    summary.add_row("NNI mean", _num(m.get("nni_mean"), "{:.2f}")
                    + "  (<1 clumped, ≈1 random, >1 regular)")
    summary.add_row("seed / fidelity", f"{packing.seed} / {params.get('fidelity', '-')}")
    fd = params.get("fidelity_detail")
    if fd:
        summary.add_row("resolution", f"{fd['spheres']} spheres, {fd['grid_cells']} grid cells, "
                        f"{fd['surface_points']} surface points per type; container grid "
                        f"{fd['container_cells']:g} cells per smallest radius"
                        + "".join(f"\n{r}" for r in fd.get("reasons", [])))
    stopped = params.get("stopped")
    if stopped:
        why = {"deadline": "time budget reached", "cancelled": "interrupted"}.get(stopped,
                                                                                 stopped)
        summary.add_row("stopped early", why)
    summary.add_section()
    certified = cert.get("certified")
    summary.add_row("certified", "[green]yes[/]" if certified else
                    ("[red]NO[/]" if certified is False else "-"))
    summary.add_row("worst overlap", _num(cert.get("worst_overlap"), "{:.2e}")
                    + f"  of the smaller object (limit {_num(tol, '{:.0e}')})")
    summary.add_row("worst wall violation", _num(cert.get("worst_outside"), "{:.2e}")
                    + f"  of an object outside (limit {_num(tol, '{:.0e}')})")
    if clearance > 0:
        none = "no pair that close"
        summary.add_row("min gap objects", _num(cert.get("min_pair_gap"), "{:.3g}", none)
                        + f"  (clearance {clearance:g})")
        summary.add_row("min gap wall", _num(cert.get("min_wall_gap"), "{:.3g}",
                                              "no object that close")
                        + f"  (clearance {clearance:g})")
    else:
        summary.add_row("clearance", "0 (objects may touch)")
    summary.add_row("checked", f"{cert.get('pairs_checked', '-')} pairs, "
                               f"{cert.get('walls_checked', '-')} objects near the wall")
    repair = params.get("repair") or {}
    if repair:
        extra = repair.get("removed_after_final")
        summary.add_row("repair", f"{repair.get('rounds', 0)} rounds, "
                                  f"{repair.get('moved', 0)} moved, "
                                  f"{repair.get('removed', 0)} removed"
                        + (f" (+{extra} final removal rounds)" if extra else ""))
    attempts = params.get("attempts") or []
    if len(attempts) > 1:
        kept = max(range(len(attempts)), key=lambda i: attempts[i]["density"])
        for i, a in enumerate(attempts):
            summary.add_row(f"attempt {i + 1}", f"{a['count']} objects, {_pct(a['density'])}"
                            f", {_seconds(a['seconds'])}" + (" (kept)" if i == kept else ""))
    console.print(summary)

    timings = packing.timings or {}
    phases = Table(title="phases", title_justify="left")
    phases.add_column("phase")
    phases.add_column("time", justify="right")
    phases.add_column("objects", justify="right")
    phases.add_column("density", justify="right")
    after = {"phase1": m.get("after_phase1"), "phase2": m.get("after_phase2"),
             "extra": m.get("after_extra")}
    labels = {"load": "load meshes", "approximate": "approximate",
              "compile": "compile kernels", "phase1": "1 place & grow",
              "phase2": "2 fill cavities", "extra": "more cavity passes",
              "other_attempts": "attempts not kept", "certify": "certify & repair"}
    for key, label in labels.items():
        if key not in timings:
            continue
        snap = after.get(key) or {}
        if key == "certify":
            snap = {"count": total, "density": m.get("density")}
        phases.add_row(label, _seconds(timings[key]), str(snap.get("count", "")),
                       _pct(snap.get("density")) if snap else "")
    for key, value in timings.items():
        if key not in labels and key != "total":
            phases.add_row(key, _seconds(value), "", "")
    if "total" in timings:
        phases.add_section()
        phases.add_row("total", _seconds(timings["total"]), str(total), _pct(m.get("density")))
    if timings:
        console.print(phases)


# --------------------------------------------------------------------------- entry point


def _configure_logging(debug: bool) -> None:
    """Engine log messages: shown with --debug; otherwise the CLI prints the warnings
    itself (from the packing), so the library loggers are kept quiet."""
    log = logging.getLogger("jampacked")
    if debug:
        if not any(getattr(h, "_jampacked_cli", False) for h in log.handlers):
            handler = logging.StreamHandler(sys.stderr)
            handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s"))
            handler._jampacked_cli = True  # type: ignore[attr-defined]
            log.addHandler(handler)
        log.setLevel(logging.DEBUG)
    elif not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())


def _error(message: str) -> None:
    text = " ".join(str(message).split()) or "unknown error"
    print(f"error: {text}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``jampacked`` command line; returns the exit status (never exits itself)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or argparse's own usage errors
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    _configure_logging(args.debug)
    try:
        return int(args.run(args))
    except UsageError as exc:
        if args.debug:
            raise
        _error(exc)
        return EXIT_USAGE
    except JampackedError as exc:
        if args.debug:
            raise
        _error(exc)
        return EXIT_ERROR
    except KeyboardInterrupt:
        if args.debug:
            raise
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
