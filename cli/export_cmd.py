"""``jampacked export``: a packing JSON -> watertight, validated mesh files.

A thin front end over :func:`jampacked.export.assemble.export_packing`. Lengths are in
container units (millimetres when printing).
"""

from __future__ import annotations

import argparse
import contextlib
import json

from rich.markup import escape

from jampacked.cli.args import UsageError, add_command, positive_float
from jampacked.cli.exits import EXIT_ERROR, EXIT_INTERRUPTED, print_error
from jampacked.cli.interrupt import CancelOnInterrupt, Terminated
from jampacked.cli.reports import consoles, print_export, print_validation, progress_bar
from jampacked.cli.scene import check_output, require_png
from jampacked.core.errors import Cancelled, InputError, JampackedError, OutputError
from jampacked.export.options import AXES, MODES, ExportOptions, Opening

EXPORT_EPILOG = """\
modes:
  union    objects (and the shell) unioned into one watertight mesh; objects that do not
           touch stay separate bodies (inside a shell they lie loose: a warning says how
           many).
  connect  one body: touching objects are fused, every other object gets a strut (a
           cylinder of --connector diameter) to its nearest neighbour or the shell, along
           a minimum spanning tree of the proximity graph.
  parts    one body per object, no union, for powder-bed batch printing; the smallest gap
           between parts is measured and must keep the packing's clearance. 3MF: one
           object per part named after its type; --split writes one file per part.

shell and openings:
  --shell T makes a wall at least T thick from the container's surface inwards. Open it so
  the objects show with --open-plane +z@0.75 (removes the shell beyond 75% of the height
  along +z; any of +x -x +y -y +z -z) or --window +y@30 (a 30 mm round hole through the
  side facing +y, in its middle or, over a torus's hole, on the wall beside it). --drain D
  adds a drainage/escape hole of diameter D through the lowest point of the shell along
  --up (default +z) for resin and powder printers. Write negative axes with '=':
  --up=-y, --open-plane=-z@0.3. Union and connect fill sealed voids (pockets between
  objects, struts and shell that could not drain); --keep-voids keeps them hollow. A
  closed shell (no opening, no drain) keeps its cavity.

examples:
  jampacked export out/packing.json --mode connect --shell 2 --up +y \\
      --open-plane +y@0.55 --drain 3 -o out/spot.3mf -o out/spot.stl --render out/spot.png
  jampacked export packing.json --mode parts -o parts.3mf
  jampacked export packing.json --mode union --resolution 0.1 -o fruit.stl

Every output path is checked before any work (format, folder, a name the folder takes, not
an input or the packing file), each --split part's too. Every file is validated as written
(closed, 2-manifold, outward, no self-intersections); only when all of them pass are they
put in place, together, so a failure or Ctrl-C leaves every earlier file as it was. STL
and PLY store 32-bit floats: far from the origin their rounding can spoil a mesh that a
3MF keeps whole (the message says so). Exit status: 0 written and valid, 1 the export
refused or failed (the message says why), 2 bad arguments, 130 interrupted (nothing
written, unless the message says the export was complete).
"""


def _axis_at(text: str, default: float | None) -> tuple[str, float]:
    """``AXIS[@NUMBER]`` -> (axis, number or ``default``). The messages leave the option's
    name out: argparse puts it before them ("argument --open-plane: ...")."""
    axis, _, value = text.partition("@")
    axis = axis.strip().lower()
    if axis in ("x", "y", "z"):
        axis = "+" + axis
    if axis not in AXES:
        raise argparse.ArgumentTypeError(
            f"the axis must be one of {', '.join(AXES)}, got {text!r}")
    if not value:
        if default is None:
            raise argparse.ArgumentTypeError(f"give AXIS@SIZE, e.g. +y@30, got {text!r}")
        return axis, default
    try:
        number = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r} is not a number") from None
    return axis, number


def parse_open_plane(text: str) -> Opening:
    """``+z@0.75`` -> Opening(plane, +z, 0.75)."""
    axis, at = _axis_at(text, 0.75)
    try:
        return Opening(kind="plane", axis=axis, at=at)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def parse_window(text: str) -> Opening:
    """``+y@30`` -> Opening(window, +y, size 30)."""
    axis, size = _axis_at(text, None)
    try:
        return Opening(kind="window", axis=axis, size=size)
    except InputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_export_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` subcommand to ``sub``."""
    p = add_command(
        sub, "export",
        help="turn a packing into watertight mesh files that print (3MF, STL, OBJ, PLY)",
        description=(
            "Build the packed objects from a packing file, join them (union, connect) or "
            "keep them apart (parts), optionally inside a shell of the container, and write "
            "validated, watertight mesh files."),
        epilog=EXPORT_EPILOG)
    p.add_argument("packing", metavar="PACKING.json", help="a packing written by 'jampacked pack'")
    p.add_argument("-o", "--output", action="append", required=True, metavar="FILE",
                   help="output file (.3mf, .stl, .obj, .ply); repeat for several formats")
    p.add_argument("--mode", choices=MODES, default="connect",
                   help="union, connect (default: one printable body) or parts")
    p.add_argument("--shell", type=positive_float, metavar="MM",
                   help="add a shell of the container with walls at least this thick")
    opening = p.add_mutually_exclusive_group()
    opening.add_argument("--open-plane", type=parse_open_plane, metavar="AXIS[@FRACTION]",
                         help="cut the shell open beyond a plane, e.g. +z@0.75")
    opening.add_argument("--window", type=parse_window, metavar="AXIS@DIAMETER",
                         help="cut a round window through the shell's side, e.g. +y@30")
    p.add_argument("--drain", type=positive_float, metavar="MM",
                   help="drainage hole of this diameter through the shell's lowest point")
    p.add_argument("--keep-voids", action="store_true",
                   help="union/connect: keep sealed voids between objects, struts and shell "
                        "hollow (by default they are filled so no resin or powder is "
                        "trapped; a closed shell always keeps its cavity)")
    p.add_argument("--up", default="+z", choices=AXES, metavar="AXIS",
                   help="the axis pointing up when printed (default +z; +y for Y-up models): "
                        "the drain goes through the lowest point along it")
    p.add_argument("--connector", type=positive_float, metavar="MM",
                   help="strut diameter for --mode connect (default: 0.2 x the smallest "
                        "object's equivalent diameter)")
    p.add_argument("--resolution", type=positive_float, metavar="MM",
                   help="simplify meshes to the printer's resolution (surfaces move by at "
                        "most this much, measured; objects that only touch can come apart)")
    p.add_argument("--split", action="store_true",
                   help="--mode parts: write one file per part (NAME_<type>_<i>.EXT, i: "
                        "the object's index among the packing's placements)")
    p.add_argument("--render", metavar="PNG",
                   help="also draw the first file written, as read back, in two shaded "
                        "views, to this .png file")
    p.add_argument("--json", action="store_true",
                   help="print the export report as JSON instead of tables")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(run=cmd_export)


def _json_failure(args: argparse.Namespace, exc: Exception) -> None:
    """With --json, a failed export still prints a JSON document (stdout), with the error;
    the error line goes to stderr as for every command."""
    if args.json:
        print(json.dumps({"mode": args.mode, "paths": [], "passed": False,
                          "error": " ".join(str(exc).split())}, indent=1))


def cmd_export(args: argparse.Namespace) -> int:
    """Run ``jampacked export``; returns the exit status."""
    from jampacked.export.assemble import export_packing

    out, err = consoles()
    try:
        for path in args.output + ([args.render] if args.render else []):
            check_output(path, "-o" if path != args.render else "--render", [args.packing],
                         "packing file")
        if args.render:  # a .png: none of the -o meshes, nor the packing's input meshes
            require_png(args.render, "--render", "render")
        try:
            options = ExportOptions(mode=args.mode, shell=args.shell,
                                    opening=args.open_plane or args.window, drain=args.drain,
                                    connector=args.connector, resolution=args.resolution,
                                    split_files=args.split, up=args.up,
                                    fill_voids=not args.keep_voids)
        except InputError as exc:
            raise UsageError(str(exc)) from None
    except UsageError as exc:
        _json_failure(args, exc)
        raise
    # active to the end: a Ctrl-C once the files are in place cannot undo them, and the
    # command then says so and keeps its status
    with CancelOnInterrupt() as cancel:
        with contextlib.ExitStack() as stack:
            progress_cb = None if args.quiet or args.json else progress_bar(stack, err)
            try:
                report = export_packing(args.packing, args.output, options,
                                        progress=progress_cb, should_cancel=cancel)
            except OutputError as exc:  # an output the arguments ask for cannot be written
                _json_failure(args, exc)
                raise UsageError(str(exc)) from None
            except Cancelled as exc:
                print_error(exc)
                return EXIT_INTERRUPTED
            except JampackedError as exc:
                _json_failure(args, exc)
                raise
            except KeyboardInterrupt as exc:
                # a second Ctrl-C held back while the files were put in place: they all were
                replaced = getattr(exc, "replaced", None)
                if not replaced:
                    raise
                print_error(f"interrupted once the export was complete: "
                            f"{', '.join(replaced)} {'was' if len(replaced) == 1 else 'were'} "
                            "written and validated.")
                return EXIT_INTERRUPTED
            except Terminated as exc:  # held back likewise
                replaced = getattr(exc, "replaced", None)
                if not replaced:
                    raise
                print_error(f"terminated once the export was complete: "
                            f"{', '.join(replaced)} {'was' if len(replaced) == 1 else 'were'} "
                            "written and validated.")
                return 128 + exc.signum
        if args.json:
            print(json.dumps(report.as_dict(), indent=1, allow_nan=False))
        elif not args.quiet:
            print_export(report, out)
            for v in report.validation[:1] if len(report.validation) > 4 else report.validation:
                print_validation(v, out)
            if len(report.validation) > 4:
                failing = sum(not v.passed for v in report.validation)
                out.print(f"... and {len(report.validation) - 1} more files, {failing} failing",
                          highlight=False)
        for w in report.warnings:
            err.print(f"[yellow]warning:[/] {escape(w)}", highlight=False)
        if args.render and report.paths:
            from jampacked.cli.render import container_of, write_render
            from jampacked.export.io import read_mesh_arrays

            v, f = read_mesh_arrays(report.paths[0])
            write_render(v, f, args.render, title=f"{report.paths[0]} ({report.mode})",
                         up=options.up, container=container_of(args.packing))
            if not args.quiet and not args.json:
                out.print(f"wrote {args.render}", highlight=False)
        if cancel.requested:
            err.print("[yellow]warning:[/] Ctrl-C came after every file was validated: the "
                      "export was completed and its files written.", highlight=False)
    return 0 if report.passed else EXIT_ERROR
