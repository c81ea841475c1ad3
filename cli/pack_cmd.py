"""``jampacked pack``: pack objects into a container and save the packing (JSON).

A thin front end over :func:`jampacked.core.api.pack`. Lengths are in container units
(millimetres when the result is meant for printing).
"""

from __future__ import annotations

import argparse
import contextlib

from rich.markup import escape

from jampacked.cli.args import add_command, fraction, non_negative_float, positive_float, seed
from jampacked.cli.cluster_args import add_cluster_arguments, cluster_client, positive_int
from jampacked.cli.exits import EXIT_INTERRUPTED
from jampacked.cli.interrupt import CancelOnInterrupt, Terminated
from jampacked.cli.reports import consoles, notes_only, print_summary, progress_bar, warn
from jampacked.cli.scene import DEFAULT_CONTAINER_SIZE, DEFAULT_TYPE_SCALE, resolve_scene
from jampacked.core.api import pack
from jampacked.core.errors import OutputError
from jampacked.core.numba_cache import compile_hint
from jampacked.core.options import CavityPassOptions, PackOptions
from jampacked.core.packing import Packing, save_packing
from jampacked.core.repair import MIX_SLACK

PACK_EPILOG = """\
shares:
  --type FILE=SHARE gives a type's target share by count, as a fraction (0.4) or a
  percent (40%). Types without a share split what is left equally; with no shares at all
  every type gets the same share. When every type has a share, the shares are normalised,
  so --type a.stl=2 --type b.stl=1 means two a's for each b (percents that do not add up
  to 100% are normalised too, with a warning).

units:
  The container's units are the scene's units (millimetres for printing).
  --container-size scales the container so its largest bounding-box side is that long;
  --type-scale multiplies the object files' coordinates (1000 turns metres into mm).

examples:
  jampacked pack default -o packing.json --preview preview.png
      Spot the cow (150 mm) filled with five kinds of fruit.
  jampacked pack vase.stl --container-size 120 --type apple.obj=40% \\
      --type lemon.obj=30% --type plum.obj -o packing.json
      40% apples, 30% lemons, 30% plums in a vase 120 mm tall (or wide).
  jampacked pack box:40x40x45 --type cube.stl --type ball.stl --clearance 0.4 \\
      --time-budget 60 --seed 7 -o packing.json --preview preview.png
      Equal shares in a 40 x 40 x 45 mm box, at least 0.4 mm between parts.
  jampacked pack box:40x40x45 --type cube.stl --type ball.stl --attempts 4 \\
      --workers 2 -o packing.json
      Four attempts on two local worker processes; the densest is kept (the same
      packing as --attempts 4 alone).

Ctrl-C stops early: the best certified packing found so far is saved (exit status 130;
nothing is saved before the first object is placed); press it again once the progress
line says "stopping: Ctrl-C" to abort without saving (presses before that count as one).
Exit status: 0 done, 1 the engine refused (the message says why and how to fix it), 2 bad
arguments.
"""


def _write_preview(packing: Packing, path: str, axis: str, saved: str) -> None:
    """The preview; a file system's refusal (a full disk, a folder made read-only during the
    run) is an error that names the file and the cause and says the packing was saved (it
    was a traceback)."""
    from jampacked.cli.preview import write_preview

    try:
        write_preview(packing, path, axis=axis)
    except OSError as exc:
        raise OutputError(f"cannot write the preview '{path}' ({exc.strerror or exc}); the "
                          f"packing was saved to '{saved}'. Free some space, or give the "
                          "preview a folder with room and write permission.") from exc


def add_pack_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``pack`` subcommand to ``sub``."""
    p = add_command(
        sub, "pack",
        help="pack objects into a container and save the packing (JSON)",
        description=(
            "Fill a container mesh as densely as possible with copies of the given object "
            "types, keeping their target shares and spreading each type evenly. Every "
            "packing is certified on the real meshes (no overlap, nothing through the wall, "
            "the clearance kept) before it is saved."),
        epilog=PACK_EPILOG)
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
        help="also write a PNG of cross-sections at 25%%, 50%% and 75%% along the "
             "--preview-axis, objects coloured by type")
    p.add_argument(
        "--preview-axis", choices=("auto", "x", "y", "z"), default="auto",
        help="the axis the preview's sections cut across: auto takes z, or the "
             "container's thinnest side where z is over twice as long (a torus lying in "
             "x-z is cut across y) (default: auto)")
    p.add_argument(
        "--container-size", type=positive_float, metavar="MM",
        help="scale the container so its largest bounding-box side is MM container units "
             f"(default: the file's own size; {DEFAULT_CONTAINER_SIZE:g} for 'default')")
    p.add_argument(
        "--type-scale", type=positive_float, metavar="S",
        help="multiply every object file's coordinates by S, e.g. 1000 for files in metres "
             f"(default: 1; {DEFAULT_TYPE_SCALE:g} for 'default', whose fruit are in metres)")
    p.add_argument(
        "--clearance", type=non_negative_float, default=0.0, metavar="MM",
        help="minimum gap between objects and to the container wall, in container units; "
             "use about 0.3-0.5 mm to print objects as separate parts (default: 0, touching "
             "allowed)")
    p.add_argument(
        "--mix-tolerance", type=fraction, metavar="TVD",
        help="how far the type mix may drift from the shares (total variation distance, 0 "
             "to 1) for the cavity passes to add an object to a small hole; the types a mix "
             "lacks late are often big ones that no longer fit, so a tight mix can leave "
             f"holes unfilled (default: {CavityPassOptions().max_tvd:g}; 0 keeps the mix as "
             "close as the count allows). Objects certification removes leave the mix within "
             f"{MIX_SLACK:g} of it (or of the placement's mix, if that is further off)")
    p.add_argument(
        "--seed", type=seed, default=0, metavar="N",
        help="random seed; the same inputs and seed give the same packing, unless the "
             "--time-budget ends the run (where it ends depends on the machine's speed) "
             "(default: 0)")
    p.add_argument(
        "--fidelity", choices=("auto", "low", "medium", "high"), default="auto",
        help="how closely the engine models object shapes while packing: low is fastest, "
             "high packs tightest; auto chooses from the scene: fewer spheres per object when "
             "thousands are expected, finer grids for elongated objects, a small clearance "
             "or a tight container (default: auto; the summary says what it chose). "
             "Certification always uses the exact meshes")
    p.add_argument(
        "--time-budget", type=positive_float, metavar="S",
        help="stop placing objects after S seconds at the latest and certify what is there: "
             "a ceiling, placement ends sooner once new attempts only repeat the best one. "
             "It starts after loading and, on the first run, compiling the engine (default: "
             "no limit; Ctrl-C also stops early)")
    p.add_argument(
        "--attempts", type=positive_int, metavar="N",
        help="run N attempts (each its own random stream from the seed and its index) and "
             "keep the densest; the same N give the same packing on one machine or a "
             "cluster. With a --time-budget, those that start before it ends (a warning "
             "says when fewer ran) (default: one attempt, or as many as fit the "
             "--time-budget; with --workers/--scheduler: one per worker)")
    add_cluster_arguments(p, "the attempts")
    p.add_argument(
        "-q", "--quiet", action="store_true",
        help="no progress bar and no summary (errors and warnings are still printed)")
    p.set_defaults(run=cmd_pack)


def cmd_pack(args: argparse.Namespace) -> int:
    """Run ``jampacked pack``; returns the exit status."""
    out, err = consoles()
    with contextlib.ExitStack() as stack:
        scene = resolve_scene(args, stack)
        for note in scene.notes:
            warn(err, note)
        client = cluster_client(args, stack)
        cancel = stack.enter_context(CancelOnInterrupt())
        progress_cb = notes_only(err) if args.quiet else progress_bar(stack, err, cancel)

        packing = pack(
            scene.container, scene.types, scene.shares, seed=args.seed,
            clearance=args.clearance, fidelity=args.fidelity, time_budget=args.time_budget,
            progress=progress_cb, should_cancel=cancel, container_size=scene.container_size,
            type_scale=scene.type_scale, names=scene.names,
            options=None if args.mix_tolerance is None
            else PackOptions(cavity=CavityPassOptions(max_tvd=args.mix_tolerance)),
            attempts=args.attempts, client=client)
    if packing.report.stopped == "cancelled" and packing.n == 0:
        # an empty packing is no result: keep what the output files held
        err.print(f"[yellow]interrupted[/] before any object was placed: nothing saved "
                  f"({escape(args.output)}"
                  + (f" and {escape(args.preview)}" if args.preview else "")
                  + " left as they were)", highlight=False)
        return EXIT_INTERRUPTED
    save_packing(packing, args.output)
    try:
        for w in packing.report.warnings:
            warn(err, w)
        hint = compile_hint(packing.timings.get("compile", 0.0))
        if hint and not args.quiet:
            err.print(f"[dim]note:[/] {escape(hint)}", highlight=False, soft_wrap=True)
        if not args.quiet:
            print_summary(packing, out)
        if args.preview:
            _write_preview(packing, args.preview, args.preview_axis, args.output)
    except Terminated as exc:  # the packing is saved: say so ("terminated" alone hid it)
        err.print(f"[yellow]terminated[/] after the packing was saved to "
                  f"{escape(args.output)}"
                  + (f"; the preview {escape(args.preview)} was not written"
                     if args.preview else ""), highlight=False)
        return 128 + exc.signum
    if not args.quiet:
        out.print(f"wrote {args.output}" + (f" and {args.preview}" if args.preview else ""),
                  highlight=False)
    if packing.report.stopped == "cancelled":
        err.print(f"[yellow]interrupted:[/] saved the best certified packing found so far "
                  f"({packing.n} objects) to {escape(args.output)}", highlight=False)
        return EXIT_INTERRUPTED
    return 0
