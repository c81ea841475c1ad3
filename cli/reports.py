"""What the commands print (rich): the progress bar, warnings, the packing summary, the
export summary and the validation tables.

Lengths and volumes are in container units (millimetres when the result is meant for
printing).
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.markup import escape
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from jampacked.cli.interrupt import CancelOnInterrupt
from jampacked.core.errors import plural
from jampacked.core.mesh_files import length_unit
from jampacked.core.packing import Packing, is_spec
from jampacked.core.placement import BEHIND, REPEATED, STACK_FULL
from jampacked.core.report import NOTE_PREFIX
from jampacked.core.summary import summarize

if TYPE_CHECKING:  # imported when needed: validation pulls in numba kernels
    from jampacked.export.assemble import ExportReport
    from jampacked.export.validate import ValidationReport


def consoles() -> tuple[Console, Console]:
    """(stdout, stderr) consoles, made per call so redirected streams are honoured."""
    return Console(file=sys.stdout), Console(file=sys.stderr)


def warn(err: Console, message: str, label: str = "warning") -> None:
    """``LABEL: MESSAGE`` on ``err`` (the stderr console)."""
    err.print(f"[yellow]{label}:[/] {escape(message)}", highlight=False, soft_wrap=True)


def notes_only(err: Console) -> Callable[[float, str], None]:
    """The engine's ``progress`` callback for a quiet run: its notes only (advice, like a
    warning), as the progress bar prints them."""
    def update(fraction: float, message: str) -> None:
        if message.startswith(NOTE_PREFIX):
            _print_note(err, message)

    return update


def _print_note(err: Console, message: str) -> None:
    err.print(f"[dim]note:[/] {escape(message[len(NOTE_PREFIX):])}", highlight=False,
              soft_wrap=True)


def progress_bar(stack: contextlib.ExitStack, err: Console,
                 cancel: CancelOnInterrupt | None = None) -> Callable[[float, str], None]:
    """A rich progress bar on ``err`` for the life of ``stack``; returns the engine's
    ``progress(fraction, message)`` callback (noting a pending Ctrl-C when ``cancel``)."""
    bar = stack.enter_context(Progress(
        TextColumn("[bold]{task.description}"), BarColumn(), TaskProgressColumn(),
        TimeElapsedColumn(), console=err, transient=False))
    task = bar.add_task("starting", total=1.0)

    def update(fraction: float, message: str) -> None:
        if message.startswith(NOTE_PREFIX):  # advice to keep in view, above the bar
            _print_note(err, message)
            return
        if cancel is not None and cancel.requested:
            message = f"{message} [yellow](stopping: Ctrl-C)[/]"
        bar.update(task, completed=min(max(fraction, 0.0), 1.0), description=message)

    return update



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

    Renders `jampacked.core.summary.summarize(packing)`, which the add-on's panel shares,
    so a packing loaded from JSON prints the same as one fresh from pack().
    """
    s = summarize(packing)
    types = Table(title=title or "packing", title_justify="left", show_footer=True)
    types.add_column("type", footer="all")
    types.add_column("count", justify="right", footer=str(s.count))
    types.add_column("share", justify="right", footer="100%" if s.count else "-")
    types.add_column("target", justify="right", footer="100%")
    types.add_column("NNI", justify="right", footer=_num(s.nni_mean, "{:.2f}"))
    for t in s.types:
        types.add_row(escape(t.name), str(t.count), _pct(t.share), _pct(t.target),
                      _num(t.nni, "{:.2f}"))
    console.print(types)

    summary = Table(show_header=False, title="quality", title_justify="left")
    summary.add_column("what", style="bold")
    summary.add_column("value")
    cs = escape(_container_label(packing))
    unit = length_unit(packing.container_path)
    summary.add_row("container", f"{cs}, volume {_volume(packing.container_volume)} {unit}³")
    summary.add_row("density", _pct(s.density) + "  (object volume / container volume)")
    summary.add_row("TVD", _num(s.tvd, "{:.3f}") + "  (type-share error: 0 = exact mix)")
    summary.add_row("NNI mean", _num(s.nni_mean, "{:.2f}")
                    + "  (<1 clumped, ≈1 random, >1 regular)")
    summary.add_row("seed / fidelity", f"{s.seed} / {s.fidelity or '-'}")
    fd = s.fidelity_detail
    if fd is not None:
        summary.add_row("resolution", f"{fd.spheres} spheres, {fd.grid_cells} grid cells, "
                        f"{fd.surface_points} surface points per type; container grid "
                        f"{fd.container_cells:.3g} cells per smallest radius"
                        + "".join(f"\n{r}" for r in fd.reasons))
    if s.stopped:
        why = {"deadline": "time budget reached", "cancelled": "interrupted"}.get(s.stopped,
                                                                                 s.stopped)
        summary.add_row("stopped early", why)
    summary.add_section()
    if s.placements == "clearance changed":
        summary.add_row("certified", "[red]no longer[/]: the packing's inputs ask another "
                        f"clearance than the {_num(s.clearance, '{:g}')} certified ('export' "
                        "checks it again)")
    elif s.placements == "changed":
        summary.add_row("certified", "[red]no longer[/]: the placements were changed after "
                        "certification, so the figures below are for other placements "
                        "('export' checks them again)")
    elif s.certified and s.placements == "unrecorded":
        summary.add_row("certified", "[green]yes[/], by an older jampacked or with its digest "
                        "removed: nothing shows the placements were not changed since "
                        "('export' certifies them again)")
    else:
        summary.add_row("certified", "[green]yes[/]" if s.certified else
                        ("[red]NO[/]" if s.certified is False else "-"))
    summary.add_row("worst overlap", _num(s.worst_overlap, "{:.2e}")
                    + f"  of the smaller object (limit {_num(s.tol, '{:.0e}')})")
    summary.add_row("worst wall violation", _num(s.worst_outside, "{:.2e}")
                    + f"  of an object outside (limit {_num(s.tol, '{:.0e}')})")
    if s.clearance > 0:
        summary.add_row("min gap objects", _num(s.min_pair_gap, "{:.3g}", "no pair that close")
                        + f"  (clearance {s.clearance:g})")
        summary.add_row("min gap wall", _num(s.min_wall_gap, "{:.3g}", "no object that close")
                        + f"  (clearance {s.clearance:g})")
    else:
        summary.add_row("clearance", "0 (objects may touch)")
    summary.add_row("checked", f"{'-' if s.pairs_checked is None else s.pairs_checked} "
                               f"pairs, {'-' if s.walls_checked is None else s.walls_checked}"
                               " objects near the wall")
    if s.repair is not None:
        summary.add_row("repair", f"{plural(s.repair.rounds, 'round')}, {s.repair.moved} moved, "
                                  f"{s.repair.removed} removed"
                                  + (f" ({s.repair.for_mix} of them for the type mix)"
                                     if s.repair.for_mix else ""))
    # why a budget was left unspent (no stop reason of the run: placement ran to its end)
    ended = next((a.stopped for a in s.attempts if a.stopped in (REPEATED, STACK_FULL)), None)
    if ended is not None and not s.stopped:
        n = len(s.attempts)
        summary.add_row("attempts ended", f"after {n} attempt{'s' if n > 1 else ''}: {ended}")
    if len(s.attempts) > 1:
        for i, a in enumerate(s.attempts):
            summary.add_row(f"attempt {i + 1}", f"{a.count} objects, {_pct(a.density)}"
                            f", {_seconds(a.seconds)}"
                            + ("" if a.certified is None
                               else f", certified {_pct(a.certified)}")
                            + (" (kept)" if i == s.kept_attempt else "")
                            + (", no extra passes: too far behind to catch up"
                               if a.stopped == BEHIND else ""))
    console.print(summary)

    if s.phases:
        phases = Table(title="phases", title_justify="left")
        phases.add_column("phase")
        phases.add_column("time", justify="right")
        phases.add_column("objects", justify="right")
        phases.add_column("density", justify="right")
        for line in s.phases:
            if line.key == "total":
                phases.add_section()
            known = line.count is not None or line.density is not None
            phases.add_row(line.label, _seconds(line.seconds),
                           "" if line.count is None else str(line.count),
                           _pct(line.density) if known else "")
        console.print(phases)


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
    unit = length_unit(report.path)
    console.print(f"  volume {_volume(report.volume)} {unit}³, bounding box {size} {unit}, "
                  f"{report.n_faces} faces; self-intersections: {report.intersecting_pairs} "
                  f"face pairs; manifold3d: {report.manifold_status}", highlight=False)
    for problem in report.problems:
        console.print(f"  [red]{escape(problem)}[/]", highlight=False)
    style = "bold green" if report.passed else "bold red"
    console.print(f"[{style}]{escape(report.summary())}[/]", highlight=False, soft_wrap=True)


def print_export(report: ExportReport, console: Console) -> None:
    """The export summary as a table."""
    t = Table(title=f"export ({report.mode})", title_justify="left", show_header=False)
    t.add_column("what")
    t.add_column("value", justify="right")
    t.add_row("objects", str(report.objects))
    t.add_row("bodies", str(report.bodies))
    t.add_row("triangles", f"{report.triangles:,}")
    if report.triangles_saved:
        t.add_row("saved by --resolution", f"{report.triangles_saved:,} triangles (surfaces "
                  f"moved at most {report.resolution_deviation:.3g})")
    if report.mode == "connect":
        t.add_row("connectors", f"{report.connectors} ({report.connector_length:.1f} long "
                                f"in all)")
        t.add_row("contacts fused", str(report.fused))
    if report.shell is not None:
        s = report.shell
        t.add_row("shell wall", f"{s.thickness:g} asked; measured min {s.measured_min:.3g}, "
                                f"median {s.measured_median:.3g}, max {s.measured_max:.3g}")
        if s.opening:
            t.add_row("opening", s.opening)
        if s.drain:
            at = "" if s.drain_at is None else " at (" + ", ".join(
                f"{c:.4g}" for c in s.drain_at) + ")"
            t.add_row("drain hole", f"{s.drain:g}{at}")
        if s.notes:
            t.add_row("shell notes", "\n".join(escape(n) for n in s.notes))
    if report.voids_filled:
        t.add_row("sealed voids filled", f"{report.voids_filled} "
                                         f"({report.voids_filled_volume:,.1f} in volume)")
    if report.min_gap is not None:
        t.add_row("smallest gap between parts", f"{report.min_gap:.4g} (clearance "
                                                f"{report.clearance:g})")
    t.add_row("volume", f"{report.volume:,.1f}")
    t.add_row("time", f"{report.timings.get('total', 0):.1f} s")
    shown = report.paths[:6]
    more = f"\n... and {len(report.paths) - len(shown)} more" if len(report.paths) > 6 else ""
    t.add_row("files", "\n".join(escape(p) for p in shown) + more)
    console.print(t)
