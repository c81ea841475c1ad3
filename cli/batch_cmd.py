"""``jampacked batch``: pack every scene a batch file lists, here or on a Dask cluster, and
write each packing plus a summary table (`core/batch.py`, `core/batch_file.py`)."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from jampacked.cli.args import UsageError, add_command
from jampacked.cli.cluster_args import add_cluster_arguments, cluster_client
from jampacked.cli.exits import EXIT_INTERRUPTED
from jampacked.cli.interrupt import CancelOnInterrupt
from jampacked.cli.reports import consoles, warn
from jampacked.core.batch import (
    SUMMARY,
    SceneResult,
    check_done,
    check_output,
    run_batch,
    scene_file,
)
from jampacked.core.batch_file import read_batch

BATCH_EPILOG = """\
batch file (TOML; mesh paths relative to its folder):
  [defaults]                     # optional: settings every scene gets
  fidelity = "low"

  [[scene]]
  name = "jar"                   # packing files: OUT/jar-c1-s1.json, ...
  containers = ["jar.stl", "box:40x40x45"]   # or container = "jar.stl"
  types = ["apple.obj", "lemon.obj"]         # or type_sets = [[...], [...]]
  shares = [0.6, 0.4]            # optional, one per type
  seeds = [1, 2, 3]              # or seed = 1
  container_size = 120           # optional, as 'jampacked pack': type_scale,
  clearance = 0.4                # fidelity, time_budget, attempts, mix_tolerance
  export = ["3mf"]               # optional: also OUT/jar-c1-s1.3mf, ... (export_mode =
  export_mode = "connect"        # union/connect/parts, export_shell = MM)

  Each [[scene]] gives containers x object sets x seeds packings.

examples:
  jampacked batch scenes.toml -o out/
  jampacked batch scenes.toml -o out/ --workers 4
  jampacked batch scenes.toml -o out/ --scheduler tcp://10.0.0.5:8786

A rerun skips the scenes whose packing file is there and verified (it loads, its mesh files'
sha256 still match, it is certified, its placements are the ones certified and its numbers
follow from them); any other file is packed again, saying why. Export files are made
again when missing, changed since written, or made with other export settings (recorded
in OUT/<scene>.exports.json); those of a packing made since are removed. Each scene's
warnings, its export's too, are printed and go in the summary's message column; the
summary's batch column holds the batch file's path, and a rerun replaces that file's rows
and keeps those of other batch files run into OUT (a scene of the same name that another
batch file beside this one wrote there is refused). Ctrl-C stops: finished scenes stay
written, and the scene being packed here writes its best certified packing so far, which
the next run packs again (exit status 130). Exit status:
0 every scene packed or skipped, 1 a scene failed or the batch file is bad (the message
names the scene and key), 2 bad arguments.
"""


def add_batch_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``batch`` subcommand to ``sub``."""
    p = add_command(
        sub, "batch",
        help="pack every scene of a batch file (TOML), here or on a Dask cluster",
        description=(
            "Pack the scenes a batch file lists (containers x object sets x seeds), one after "
            "another or side by side on Dask workers, writing each packing as OUT/<scene>.json "
            f"and a summary table OUT/{SUMMARY}."),
        epilog=BATCH_EPILOG)
    p.add_argument("file", metavar="FILE", help="the batch file (TOML)")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="folder for the packings and the summary (created if missing)")
    add_cluster_arguments(p, "the scenes", reads_files=True)
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress bar and no table (errors are still printed)")
    p.set_defaults(run=cmd_batch)


def cmd_batch(args: argparse.Namespace) -> int:
    """Run ``jampacked batch``; returns the exit status."""
    out, err = consoles()
    if not args.output.strip():  # else the current folder, silently
        raise UsageError("-o is empty: give a folder, e.g. -o out (it is created if missing)")
    scenes = read_batch(args.file)
    check_output(scenes, args.output, args.file)  # before a cluster starts or a scene is packed
    with contextlib.ExitStack() as stack:
        # no cluster to start when every scene is already done and verified
        checked = {s.id: check_done(s, scene_file(args.output, s)) for s in scenes}
        todo = any(done is None for done, _ in checked.values())
        client = cluster_client(args, stack, needed=todo)
        cancel = stack.enter_context(CancelOnInterrupt())
        progress = None
        if not args.quiet:
            bar = stack.enter_context(Progress(
                TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), console=err))
            task = bar.add_task("scenes", total=len(scenes))

            def progress(done: int, total: int, message: str) -> None:
                stopping = " [yellow](stopping: Ctrl-C)[/]" if cancel.requested else ""
                bar.update(task, completed=done, description=escape(message) + stopping)

        results = run_batch(scenes, args.output, client, progress, cancel, checked,
                            batch=str(Path(args.file).resolve()))
    if not args.quiet:
        print_results(results, out)
        out.print(f"wrote {args.output}/{SUMMARY}", highlight=False)
    for r in results:
        if r.status == "failed":
            err.print(f"[red]failed:[/] {escape(r.spec.id)}: {escape(r.message)}",
                      highlight=False, soft_wrap=True)
        if r.status == "cancelled" and r.file:
            err.print(f"note: {escape(r.spec.id)}: {escape(r.message)}", highlight=False,
                      soft_wrap=True)
        if r.repacked:
            err.print(f"note: {escape(r.spec.id)} packed again: the earlier file was not "
                      f"trusted: {escape(r.repacked)}", highlight=False, soft_wrap=True)
        for why in r.reexported:
            err.print(f"note: {escape(r.spec.id)} exported again: {escape(why)}",
                      highlight=False, soft_wrap=True)
        for why in r.removed:
            err.print(f"note: {escape(r.spec.id)}: {escape(why)}",
                      highlight=False, soft_wrap=True)
        for w in r.warnings():
            warn(err, f"{r.spec.id}: {w}")
    if cancel.requested:
        return EXIT_INTERRUPTED
    return 1 if any(r.status == "failed" for r in results) else 0


def print_results(results: list[SceneResult], console) -> None:
    """The summary table: one row per scene."""
    table = Table(title="batch")
    for name in ("scene", "status", "objects", "density", "TVD", "certified", "s"):
        table.add_column(name, justify="left" if name in ("scene", "status") else "right")
    for r in results:
        p = r.packing
        table.add_row(
            escape(r.spec.id), r.status, "" if p is None else str(p.n),
            "" if p is None else f"{p.metrics['density']:.1%}",
            "" if p is None else f"{p.metrics['tvd']:.3f}",
            "" if p is None else ("yes" if p.certificate.get("certified") else "NO"),
            "" if r.seconds is None else f"{r.seconds:.1f}")
    console.print(table)
