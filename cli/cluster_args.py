"""``--workers K`` / ``--scheduler ADDRESS``: the Dask cluster a command runs on (shared by
``pack`` and ``batch``)."""

from __future__ import annotations

import argparse
import contextlib

from jampacked.cli.args import UsageError


def positive_int(text: str) -> int:
    """A whole number >= 1 (argparse names the option before the message)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more, got {text!r}")
    return value


def add_cluster_arguments(p: argparse.ArgumentParser, what: str,
                          reads_files: bool = False) -> None:
    """Add --workers and --scheduler to `p`; `what` says what runs on the workers, which
    open the mesh files themselves when `reads_files`."""
    p.add_argument(
        "--workers", type=positive_int, metavar="K",
        help=f"run {what} on K local worker processes (a Dask LocalCluster started for this "
             "command)")
    p.add_argument(
        "--scheduler", metavar="ADDRESS",
        help=f"run {what} on an existing Dask cluster, e.g. tcp://10.0.0.5:8786 (start one "
             "with 'dask scheduler' and 'dask worker ADDRESS' on each machine, where the same "
             "jampacked is installed" + ("; the mesh files must be readable at the same paths "
                                         "there)" if reads_files else ")"))


def cluster_client(args: argparse.Namespace, stack: contextlib.ExitStack,
                   needed: bool = True):
    """The distributed.Client the arguments ask for (closed with `stack`), or None (also
    when not `needed`: nothing to run)."""
    if args.workers is not None and args.scheduler is not None:
        raise UsageError("give --workers or --scheduler, not both")
    if not needed or (args.workers is None and args.scheduler is None):
        return None
    from jampacked.core.cluster import client_for

    return stack.enter_context(client_for(args.scheduler, workers=args.workers))
