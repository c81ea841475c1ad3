"""Metrics of a packing as custom properties and panel lines (no bpy: plain values).

The result collection of a Pack carries these custom properties (``jampacked_`` prefix):
count, count_per_type, type_names, target_shares, density, tvd, nni_mean, nni_per_type
(-1 where a type has fewer than two objects), certified, worst_overlap, worst_outside,
min_pair_gap and min_wall_gap (with a clearance), clearance, seed, fidelity, stopped,
time_s, warnings (when the run has any), plus the packing JSON (``jampacked_packing``).
Definitions: DESIGN.md.
"""

from __future__ import annotations

import colorsys
import re
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from jampacked.core.packing import Packing

PREFIX = "jampacked_"

#: custom property -> description shown in Blender's UI
DESCRIPTIONS = {
    "count": "Objects placed",
    "count_per_type": "Objects placed per type, in the order of type_names",
    "type_names": "Object types, in packing order",
    "target_shares": "Target share of each type (normalised)",
    "density": "Placed mesh volume / container mesh volume",
    "tvd": "Type-share error: total variation distance of the achieved shares from the "
           "targets (0 = exact mix)",
    "nni_mean": "Clark-Evans nearest neighbour index, count-weighted mean over types "
                "(<1 clumped, ~1 random, >1 regular)",
    "nni_per_type": "Clark-Evans index per type (-1: fewer than two objects of the type)",
    "certified": "Every overlap and wall violation checked exactly on the meshes is within "
                 "tolerance",
    "worst_overlap": "Largest pairwise intersection volume / the smaller object's volume",
    "worst_outside": "Largest object volume outside the container / the object's volume",
    "min_pair_gap": "Smallest gap between two objects (checked with a clearance)",
    "min_wall_gap": "Smallest gap between an object and the wall (checked with a clearance)",
    "clearance": "Clearance asked for (scene units)",
    "seed": "Random seed",
    "fidelity": "Fidelity used",
    "stopped": "Why placement stopped early (deadline: time budget; cancelled: finished "
               "early), empty when it ran to the end",
    "time_s": "Seconds the packing took",
    "type_volumes": "Mesh volume of each type at scale 1 (scene units^3), in the order of "
                    "type_names",
    "container_volume": "Mesh volume of the container (scene units^3)",
    "warnings": "What the run warns about (a type never placed, a mix off its shares, a "
                "time budget that ended early), one sentence each",
}


def _number(value: Any) -> float | None:
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if f == f and abs(f) != float("inf") else None


def collection_properties(packing: Packing) -> dict[str, Any]:
    """The custom properties of a result collection (keys without the prefix), from the
    packing's summary (`jampacked.core.summary`).

    Values are ints, floats, strings, bools or lists of them (what Blender's ID properties
    hold); undefined values are left out, except per-type NNI (-1).
    """
    from jampacked.core.summary import summarize

    summ = summarize(packing)
    out: dict[str, Any] = {
        "count": summ.count,
        "count_per_type": [t.count for t in summ.types],
        "type_names": [t.name for t in summ.types],
        "target_shares": [float(t.target) for t in summ.types],
        "nni_per_type": [t.nni if t.nni is not None else -1.0 for t in summ.types],
        "certified": bool(summ.certified),
        "seed": int(summ.seed),
        "fidelity": summ.fidelity,
        "stopped": summ.stopped or "",
        "type_volumes": [float(t.volume) for t in packing.types],
    }
    if packing.container_volume > 0:
        out["container_volume"] = float(packing.container_volume)
    for key in ("density", "tvd", "nni_mean", "worst_overlap", "worst_outside",
                "min_pair_gap", "min_wall_gap", "clearance"):
        value = _number(getattr(summ, key))
        if value is not None:
            out[key] = value
    if summ.total_seconds is not None:
        out["time_s"] = summ.total_seconds
    if packing.report.warnings:
        out["warnings"] = [in_blender_words(str(w)) for w in packing.report.warnings]
    return out


def _get(props: Mapping[str, Any], key: str, default: Any = None) -> Any:
    return props.get(PREFIX + key, default)


#: the engine's messages name the command line's options; in Blender the same advice is
#: about the scene's objects and the panel's fields (longest first)
_BLENDER_WORDS = (
    (" (CLI: --type FILE[=SHARE])", ""),
    # the whole phrase first: a Clearance field takes its unit ("0.2 mm") in any scene
    ("--clearance (e.g. --clearance 0.2 for 0.2 mm)", "a Clearance (e.g. 0.2 mm)"),
    ("export with --mode union or --mode connect", "export in Union or Connect mode"),
    ("export with --mode union or --mode parts", "export in Union or Parts mode"),
    ("export with --mode connect", "export in Connect mode"),
    ("; then export again.", "; then pack again."),
    ("(--container-size and --type-scale) and pack again.",
     "(the scene's Unit Scale, Scene Properties > Units) and pack again."),
    ("--type-scale / type_scale", "the type objects' scale"),
    ("--container-size / container_size", "the container object's scale"),
    ("--type-scale", "the type objects' scale"),
    ("--container-size", "the container object's scale"),
    ("--time-budget / time_budget", "Time Budget"),
    ("--time-budget", "Time Budget"),
    ("--mix-tolerance", "Mix Tolerance"),
    ("--clearance", "Clearance"),
    ("--fidelity high / fidelity='high'", "Fidelity High"),
    ("--fidelity", "Fidelity"),
    # export: the add-on exports with +z up and names an opening by its panel's words
    (", or give another --up (the drain goes under the cavity's lowest point)", ""),
    ("--open-plane or --window", "an Opening (Plane or Window)"),
    ("--keep-voids", "Fill Sealed Voids off"),
    ("--mode parts", "Parts mode"),
    ("Ctrl-C stops them", "Finish Now stops them"),
    ("--resolution", "Resolution"),
    ("--shell", "Shell"),
    ("--drain", "Drain"),
    ("--connector", "Connector"),
    # a mesh's defects are fixed in Edit Mode, not by exporting a file again
    ("Check that the right file was exported; re-export it from your modelling tool as a "
     "closed solid.", "Check that it is the right object, and make it a closed solid in Edit "
     "Mode."),
    ("re-export it from your modelling tool as a closed solid",
     "make it a closed solid in Edit Mode (Make Manifold in this panel mends holes and "
     "flipped faces)"),
    # in Blender the placements change by moving, adding or deleting objects and points
    ("Every object must sit within the container: re-run the packing, or fix these "
     "placements.", "Every object must sit within the container: move these objects back "
     "inside, or pack again."),
    ("re-run the packing, or fix or remove these placements",
     "pack again, or fix or delete these objects"),
    ("re-run the packing, or fix these placements", "pack again, or fix these objects"),
    ("the packing was changed after it was certified (its certificate's digest no longer "
     "matches its placements)", "the result's objects were moved, added or deleted since "
     "Pack certified them"),
)


#: Export writes millimetres (`units.mm_per_unit` scales the scene): the export's
#: messages say "units", its command line's container units, where they are millimetres
_EXPORT_UNITS = (
    (" units (mm)", " mm"),
    ("(container units)", "(mm)"),
    (" units³", " mm³"),
    (" units^3", " mm³"),
    (" units across", " mm across"),
    (" units from its surface", " mm from its surface"),
    (" units of another face", " mm of another face"),
)


_NUMBER = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
#: a length before the word that says what it measures ("0.839 apart")
_LENGTH_BEFORE = re.compile(rf"(?<![\w.])({_NUMBER}) (across|apart|away|higher|lower|long|"
                            r"thick|wide|under)\b")
#: a length after the field or setting it is ("Connector 4.6", "the clearance 1"), whole
#: (not "0" of "0.25") and not already in mm
_LENGTH_AFTER = re.compile(rf"\b(Connector|Clearance|clearance|Resolution|Shell|Drain) "
                           rf"({_NUMBER})(?![\w.])(?! ?mm)")
#: a point ("at (-39.86, -21.21, 174.3)")
_POINT = re.compile(rf"(\((?:{_NUMBER}, ){{2}}{_NUMBER}\))(?! ?mm)")
#: a name in quotes (an object's, a file's): left as it is (an apostrophe inside a word,
#: "the cavity's", opens none)
_QUOTED = re.compile(r"((?<!\w)'[^']*'(?!\w))")


def export_in_mm(message: str) -> str:
    """An export message (in Blender's words: `in_blender_words` first) with its lengths'
    unit said as millimetres, what the add-on's exports are in: the numbers it suggests
    for a field can be typed in as they read ("4.6 mm"), whatever the scene's unit."""
    for cli, blender in _EXPORT_UNITS:
        message = message.replace(cli, blender)
    parts = _QUOTED.split(message)
    for k in range(0, len(parts), 2):  # the text between quoted names
        part = _LENGTH_BEFORE.sub(r"\1 mm \2", parts[k])
        part = _LENGTH_AFTER.sub(r"\1 \2 mm", part)
        parts[k] = _POINT.sub(r"\1 mm", part)
    return "".join(parts)


def in_blender_words(message: str) -> str:
    """An engine message with the command line's option names replaced by what a Blender
    user changes instead, first letter upper case."""
    for cli, blender in _BLENDER_WORDS:
        message = message.replace(cli, blender)
    return message[:1].upper() + message[1:]


def warnings(props: Mapping[str, Any]) -> list[str]:
    """The run's warnings stored on a result collection (none for results made before
    they were stored)."""
    return [str(w) for w in _get(props, "warnings", [])]


#: densities closer than this are the same (the stored one is the packing's, the one
#: now is summed again from the scene's single-precision scales)
DENSITY_SAME = 1e-5


def density_now(props: Mapping[str, Any], scale_cubes: Mapping[int, float]) -> float | None:
    """The density of what a result holds now: ``scale_cubes`` maps each type index to the
    sum of its placed objects' scale cubed; None for a result that does not record its
    volumes."""
    volumes = list(_get(props, "type_volumes", []))
    container = _number(_get(props, "container_volume"))
    if not container or any(not 0 <= t < len(volumes) for t in scale_cubes):
        return None
    return sum(float(volumes[t]) * c for t, c in scale_cubes.items()) / container


def panel_lines(props: Mapping[str, Any], mm_per_unit: float | None = None,
                now: tuple[int, float | None] | None = None) -> list[tuple[str, str]]:
    """(label, value) rows for the panel, read from a result collection's properties;
    with `mm_per_unit` (`units.mm_per_unit`) the gaps in millimetres, as exported. The
    figures are the packing's; ``now`` (objects, density or None) is what the result holds
    now, shown where it differs (an artist deleted, added or rescaled placed objects)."""
    def pct(x: Any) -> str:
        v = _number(x)
        return "-" if v is None else f"{v:.1%}"

    def num(x: Any, fmt: str) -> str:
        v = _number(x)
        return "-" if v is None else format(v, fmt)

    rows: list[tuple[str, str]] = []
    names = list(_get(props, "type_names", []))
    counts = list(_get(props, "count_per_type", []))
    targets = list(_get(props, "target_shares", []))
    nni = list(_get(props, "nni_per_type", []))
    total = int(_get(props, "count", 0) or 0)
    for t, name in enumerate(names):
        c = int(counts[t]) if t < len(counts) else 0
        share = c / total if total else 0.0
        target = targets[t] if t < len(targets) else None
        r = nni[t] if t < len(nni) and nni[t] is not None and nni[t] >= 0 else None
        rows.append((name, f"{c}  ({pct(share)} / {pct(target)})  NNI {num(r, '.2f')}"))
    rows.append(("Objects", str(total)))
    rows.append(("Density", pct(_get(props, "density"))))
    density = _number(_get(props, "density"))
    if now is not None and (now[0] != total or (now[1] is not None and density is not None
                                                and abs(now[1] - density) > DENSITY_SAME)):
        rows.append(("Holds now", f"{now[0]} objects" + ("" if now[1] is None
                                                          else f", {pct(now[1])}")))
    rows.append(("TVD", num(_get(props, "tvd"), ".3f")))
    rows.append(("NNI mean", num(_get(props, "nni_mean"), ".2f")))
    certified = _get(props, "certified")
    rows.append(("Certified", "yes" if certified else ("NO" if certified is not None else "-")))
    rows.append(("Worst overlap", num(_get(props, "worst_overlap"), ".2e")))
    rows.append(("Worst outside", num(_get(props, "worst_outside"), ".2e")))
    if _number(_get(props, "clearance")):
        for label, key in (("Min gap objects", "min_pair_gap"), ("Min gap wall", "min_wall_gap")):
            gap = _number(_get(props, key))
            rows.append((label, "-" if gap is None else f"{gap:.3g}" if mm_per_unit is None
                         else f"{gap * mm_per_unit:.3g} mm"))
    stopped = _get(props, "stopped")
    if stopped:
        rows.append(("Stopped", {"deadline": "time budget", "cancelled": "finished early"}
                     .get(stopped, stopped)))
    rows.append(("Time", num(_get(props, "time_s"), ".1f") + " s"))
    return rows


def type_colour(index: int) -> tuple[float, float, float, float]:
    """A distinct, saturated RGBA colour per type (golden-ratio hue steps)."""
    hue = (0.08 + 0.618034 * index) % 1.0
    r, g, b = colorsys.hsv_to_rgb(hue, 0.65, 0.9)
    return (r, g, b, 1.0)
