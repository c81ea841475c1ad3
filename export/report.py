"""What an export wrote and how it checked (:func:`jampacked.export.assemble.export_packing`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .validate import ValidationReport

if TYPE_CHECKING:
    from .shell import ShellReport

__all__ = ["ExportReport"]


@dataclass
class ExportReport:
    """What an export wrote and how it checked.

    paths: files written. bodies: bodies in the result (1 for a connected export).
    triangles: triangles of the result (per file for parts split into files: the sum).
    triangles_saved: triangles --resolution removed; resolution_deviation: how far that
    moved a surface at most (measured, container units). connectors / connector_length /
    connector_diameter: struts added (connect mode), their total visible length and their
    diameter (container units); connectors_refused: struts dropped because they would
    have left the container. fused: tree edges whose solids already overlapped. min_gap:
    smallest gap between parts (parts mode; None when no two parts are near), clearance:
    the packing's clearance. voids_filled /
    voids_filled_volume: sealed voids made solid (see ExportOptions.fill_voids) and their
    volume (container units cubed).
    """

    mode: str
    paths: list[str]
    bodies: int
    objects: int
    triangles: int
    triangles_saved: int = 0
    resolution_deviation: float = 0.0
    connectors: int = 0
    connector_length: float = 0.0
    connector_diameter: float = 0.0
    connectors_refused: int = 0
    fused: int = 0
    min_gap: float | None = None
    clearance: float = 0.0
    volume: float = 0.0
    voids_filled: int = 0
    voids_filled_volume: float = 0.0
    shell: ShellReport | None = None
    validation: list[ValidationReport] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        """Every written file validated."""
        return bool(self.validation) and all(v.passed for v in self.validation)

    def summary(self, unit: str = "") -> str:
        """One paragraph for people; ``unit`` names the lengths' unit where the reader does
        not know it (Blender's scenes in metres export in millimetres: "mm")."""
        u = f" {unit}" if unit else ""
        volume = f"{u}³" if unit else " in volume"
        parts = [f"{self.mode}: {self.objects} objects -> {self.bodies} "
                 f"bod{'y' if self.bodies == 1 else 'ies'}, {self.triangles:,} triangles"]
        if self.mode == "connect":
            parts.append(f"{self.connectors} connectors, {self.connector_length:.1f}{u} long "
                         f"in all, {self.fused} contacts fused")
        if self.shell is not None:
            parts.append(f"shell {self.shell.thickness:g}{u} thick (measured median "
                         f"{self.shell.measured_median:.3g}, min "
                         f"{self.shell.measured_min:.3g}{u})")
            parts += [note.rstrip(".") for note in self.shell.notes]
        if self.min_gap is not None:
            parts.append(f"smallest gap between parts {self.min_gap:.3g}{u} (clearance "
                         f"{self.clearance:g}{u})")
        if self.triangles_saved:
            parts.append(f"--resolution saved {self.triangles_saved:,} triangles (surfaces "
                         f"moved at most {self.resolution_deviation:.3g}{u})")
        if self.voids_filled:
            parts.append(f"{self.voids_filled} sealed void{'s' if self.voids_filled > 1 else ''}"
                         f" filled ({self.voids_filled_volume:.3g}{volume})")
        verdict = "PASS" if self.passed else "FAIL"
        parts.append(f"validation {verdict} for {len(self.validation)} file(s)")
        return "; ".join(parts) + "."

    def as_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode, "paths": self.paths, "bodies": self.bodies,
            "objects": self.objects, "triangles": self.triangles,
            "triangles_saved": self.triangles_saved,
            "resolution_deviation": self.resolution_deviation, "connectors": self.connectors,
            "connector_length": self.connector_length,
            "connector_diameter": self.connector_diameter,
            "connectors_refused": self.connectors_refused, "fused": self.fused,
            "min_gap": self.min_gap, "clearance": self.clearance, "volume": self.volume,
            "voids_filled": self.voids_filled, "voids_filled_volume": self.voids_filled_volume,
            "shell": self.shell.as_dict() if self.shell else None,
            "validation": [v.as_dict(max_indices=20) for v in self.validation],
            "passed": self.passed, "timings": self.timings, "warnings": self.warnings,
        }
