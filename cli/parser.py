"""The argument parser of the ``jampacked`` command: its description, examples and the
subcommands (each added by its own module)."""

from __future__ import annotations

import argparse

from jampacked.cli.args import FORMATTER, Parser, fill
from jampacked.cli.batch_cmd import add_batch_parser
from jampacked.cli.export_cmd import add_export_parser
from jampacked.cli.info_cmd import add_info_parser
from jampacked.cli.pack_cmd import add_pack_parser
from jampacked.cli.validate_cmd import add_validate_parser

MAIN_EPILOG = """\
examples:
  jampacked pack default -o packing.json --preview preview.png
  jampacked pack vase.stl --container-size 120 --type apple.obj=40% \\
      --type lemon.obj=30% --type plum.obj -o packing.json
  jampacked pack box:40x40x45 --type cube.stl --type ball.stl --clearance 0.4 \\
      --time-budget 60 -o packing.json
  jampacked export out/packing.json --mode connect --shell 2 --up +y \\
      --open-plane +y@0.55 --drain 3 -o out/spot.3mf -o out/spot.stl
  jampacked info packing.json
  jampacked validate out/spot.3mf
  jampacked batch scenes.toml -o out/ --workers 2

Run 'jampacked COMMAND --help' for the options of a command.
Lengths are in container units: millimetres when the result is meant for printing.
"""

#: subcommands, in the order of the help text
COMMANDS = (add_pack_parser, add_export_parser, add_info_parser, add_validate_parser,
            add_batch_parser)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``jampacked`` command."""
    parser = Parser(
        prog="jampacked",
        description=fill(
            "Pack 3D objects densely into a container mesh: mixed types at target shares, "
            "no clumps of one type, every placement certified on the real meshes."
        ),
        epilog=MAIN_EPILOG,
        formatter_class=FORMATTER,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {package_version()}")
    parser.add_argument(
        "--debug", action="store_true",
        help="show full tracebacks and the engine's log messages")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    sub.required = True
    for add in COMMANDS:
        add(sub)
    return parser


def package_version() -> str:
    """The installed package's version, for ``--version``."""
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return "unknown"
    try:
        return version("jampacked")
    except PackageNotFoundError:
        return "(not installed)"


