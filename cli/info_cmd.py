"""``jampacked info``: summarise a saved packing and check its mesh files."""

from __future__ import annotations

import argparse

from rich.markup import escape

from jampacked.cli.args import add_command
from jampacked.cli.exits import EXIT_ERROR
from jampacked.cli.reports import consoles, print_summary, warn
from jampacked.core.batch_verify import wrong_metric
from jampacked.core.packing import is_spec, load_packing, verify_sources
from jampacked.core.packing_digest import (
    only_clearance_changed,
    placements_status,
    uncertified_since,
)

INFO_EPILOG = """\
examples:
  jampacked info packing.json

Exit status: 0 all good, 1 the file cannot be read, a mesh file it names is missing or
has changed since the packing was made, or its figures or placements were edited.
"""


def add_info_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``info`` subcommand to ``sub``."""
    p = add_command(
        sub, "info",
        help="summarise a saved packing and check its mesh files",
        description=(
            "Print the summary of a saved packing (objects per type, density, type-share "
            "error, clumping, certification, timings) and check that the mesh files it "
            "names are present and unchanged (sha256)."),
        epilog=INFO_EPILOG)
    p.add_argument("packing", metavar="PACKING.json", help="a packing written by 'jampacked pack'")
    p.set_defaults(run=cmd_info)


def cmd_info(args: argparse.Namespace) -> int:
    """Run ``jampacked info``; returns the exit status."""
    out, err = consoles()
    packing = load_packing(args.packing)
    print_summary(packing, out, title=f"packing {args.packing}")
    for w in packing.report.warnings:  # the run's, recorded in the file: not news
        warn(err, w, "warned when packed")
    problems = [f"[red]source:[/] {escape(p)}" for p in verify_sources(packing)]
    if only_clearance_changed(packing):
        problems.insert(0, f"[red]clearance:[/] the packing {escape(uncertified_since(packing))}"
                        ": 'jampacked export' certifies it again with the clearance asked, "
                        "or pack again")
    elif placements_status(packing) == "changed":
        problems.insert(0, "[red]placements:[/] changed after the packing was certified (its "
                        "certificate's digest no longer matches the placements, frames, "
                        "volumes or certificate): 'jampacked export' certifies them again "
                        "before it exports them, or pack again")
    wrong = wrong_metric(packing, missing_ok=True)
    if wrong:
        problems.insert(0, f"[red]metrics:[/] {escape(wrong)}: the figures above are not "
                        "this packing's; pack again for true ones")
    n_files = len(packing.types) + (0 if is_spec(packing.container_path) else 1)
    if problems:
        for p in problems:
            err.print(p, highlight=False, soft_wrap=True)
        return EXIT_ERROR
    out.print(f"sources: all {n_files} mesh files present and unchanged", highlight=False)
    return 0
