"""Scene units for printing: Blender units (BU) to the millimetres that print files hold.

Blender reads lengths as ``scale_length`` metres per BU when the scene has a unit system
(Metric or Imperial; the default scene: 1 BU = 1 m). 3MF declares millimetres and STL, OBJ
and PLY are read as millimetres by slicers, so Export multiplies lengths by
``scale_length * 1000``, as the 3D-Print Toolbox applies the scene's scale. A scene with no
unit system is read as 1 BU = 1 mm. Packing itself stays in BU. No bpy here.
"""

from __future__ import annotations

#: the unit system of a scene without units (Scene > Units > Unit System: None)
NO_UNITS = "NONE"


def mm_per_unit(system: str, scale_length: float) -> float:
    """Millimetres per Blender unit of a scene with ``unit_settings.system`` and
    ``unit_settings.scale_length``."""
    if system == NO_UNITS or scale_length <= 0:
        return 1.0
    return float(scale_length) * 1000.0


def _length(mm: float) -> str:
    for unit, size in (("m", 1000.0), ("cm", 10.0)):
        if mm >= size:
            return f"{mm / size:g} {unit}"
    return f"{mm:g} mm"


def units_line(system: str, scale_length: float) -> str:
    """The panel's statement of the export units, e.g. "1 BU = 1 m, exported in mm"."""
    mm = mm_per_unit(system, scale_length)
    if system == NO_UNITS:
        return "No scene units: 1 BU exported as 1 mm"
    return f"1 BU = {_length(mm)}, exported in mm"
