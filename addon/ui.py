"""The "Jampacked" tab of the 3D viewport sidebar: Pack, Result, Export and Validate panels."""

# No "from __future__ import annotations": Blender reads class annotations.
import bpy

from . import instances, result_edits, results, summary, units, worker


class JAMPACKED_UL_types(bpy.types.UIList):
    """Object types: object, share and its normalised percentage."""

    def draw_item(self, context: bpy.types.Context, layout: bpy.types.UILayout,
                  data: bpy.types.PropertyGroup, item: bpy.types.PropertyGroup, icon: int,
                  active_data: bpy.types.PropertyGroup, active_propname: str, index: int = 0,
                  flt_flag: int = 0) -> None:
        total = sum(t.share for t in data.types) or 1.0
        row = layout.row(align=True)
        row.prop(item, "object", text="", icon='MESH_DATA')
        sub = row.row(align=True)
        sub.scale_x = 0.6
        sub.prop(item, "share", text="")
        row.label(text=f"{item.share / total:.0%}")


class _Sidebar:
    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "Jampacked"


class JAMPACKED_PT_pack(_Sidebar, bpy.types.Panel):
    """Container, object types, settings and the Pack button with its progress."""

    bl_label = "Jampacked"
    bl_idname = "JAMPACKED_PT_pack"

    def draw(self, context: bpy.types.Context) -> None:
        layout = self.layout
        s = context.scene.jampacked
        state = context.window_manager.jampacked_job
        layout.prop(s, "container", icon='MESH_CUBE')
        layout.label(text="Object Types")
        row = layout.row()
        row.template_list("JAMPACKED_UL_types", "", s, "types", s, "active_type", rows=3)
        col = row.column(align=True)
        col.operator("jampacked.type_add", icon='ADD', text="")
        col.operator("jampacked.type_remove", icon='REMOVE', text="")
        col.separator()
        col.operator("jampacked.type_move", icon='TRIA_UP', text="").direction = 'UP'
        col.operator("jampacked.type_move", icon='TRIA_DOWN', text="").direction = 'DOWN'
        col = layout.column(align=True)
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(s, "seed")
        col.prop(s, "clearance")
        col.prop(s, "fidelity")
        col.prop(s, "mix_tolerance")
        col.prop(s, "time_budget")
        col.prop(s, "keep_previous")
        col.prop(s, "result_kind")
        if s.result_kind == 'AUTO':
            col.prop(s, "instance_threshold")
        if state.running:
            box = layout.box()
            box.progress(factor=state.fraction, type='BAR',
                         text=f"{state.title} {state.fraction:.0%}")
            box.label(text=state.message or "starting")
            row = box.row(align=True)
            if state.stopping:
                row.label(text="Stopping...", icon='TIME')
            else:
                row.operator("jampacked.cancel", text="Cancel", icon='CANCEL').action = 'CANCEL'
                if state.title == "Packing":
                    row.operator("jampacked.cancel", text="Finish Now",
                                 icon='CHECKMARK').action = 'FINISH'
        else:
            _draw_warm_up(layout)
            layout.operator("jampacked.pack", icon='PLAY')
        if state.last_message and not state.running:
            icon = {'ERROR': 'ERROR', 'WARNING': 'ERROR'}.get(state.last_level, 'INFO')
            col = layout.column(align=True)
            for i, line in enumerate(_wrap(state.last_message, 48)):
                col.label(text=line, icon=icon if i == 0 else 'BLANK1')


def _draw_warm_up(layout: bpy.types.UILayout) -> None:
    """While the engine compiles in the background: what it does and how far it is (Pack
    can be pressed meanwhile: it waits for the compile, then its budget starts)."""
    snap = worker.warm_up_snapshot()
    if snap is None or snap.state != worker.RUNNING:
        return
    box = layout.box()
    box.progress(factor=snap.fraction, type='BAR',
                 text=f"{worker.WARM_UP_TITLE}\u2026 {snap.fraction:.0%}")
    box.label(text=f"{snap.message} ({snap.elapsed:.0f} s)", icon='TIME')


def _wrap(text: str, width: int) -> list[str]:
    """Split a message into lines of about ``width`` characters for labels."""
    lines: list[str] = []
    line = ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            lines.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    if line:
        lines.append(line)
    return lines[:12]


#: the last count of an instanced result, keyed by what changes when points are deleted,
#: added or made real or the instances object is moved: a panel redraws often, and reading
#: 100,000 points each time took 0.1 s (an object result, under the instancing threshold,
#: is summed at each redraw, so that a placed object rescaled shows at once)
_HELD: dict[int, tuple[tuple, tuple[int, float | None] | None]] = {}


def _held_now(coll: bpy.types.Collection) -> tuple[int, float | None] | None:
    """(objects, density or None) the result holds now; None where it cannot be read (a
    points object whose attributes a script removed: the panel still draws)."""
    from jampacked.core.errors import JampackedError

    points = instances.points_object(coll)
    key = None if points is None else (
        len(coll.all_objects), len(points.data.vertices),
        tuple(tuple(row) for row in points.matrix_world))
    cached = _HELD.get(coll.as_pointer())
    if key is not None and cached is not None and cached[0] == key:
        return cached[1]
    try:
        count, cubes = result_edits.held_now(coll)
        now: tuple[int, float | None] | None = (count, summary.density_now(coll, cubes))
    except (JampackedError, KeyError, ReferenceError):  # what a script left of the result
        now = None
    _HELD.clear()  # one result is shown at a time
    if key is not None:
        _HELD[coll.as_pointer()] = (key, now)
    return now


class JAMPACKED_PT_result(_Sidebar, bpy.types.Panel):
    """Metrics of the active object's result, else the last Pack's (read from its
    collection's custom properties), and its Make Real buttons."""

    bl_label = "Result"
    bl_parent_id = "JAMPACKED_PT_pack"

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return results.shown_result(context) is not None

    def draw(self, context: bpy.types.Context) -> None:
        coll = results.shown_result(context)
        layout = self.layout
        layout.label(text=coll.name, icon='OUTLINER_COLLECTION')
        col = layout.column(align=True)
        unit = context.scene.unit_settings
        now = _held_now(coll)
        for label, value in summary.panel_lines(coll, units.mm_per_unit(unit.system,
                                                                         unit.scale_length),
                                                now):
            row = col.row()
            row.label(text=label)
            row.label(text=value)
        for warning in summary.warnings(coll):
            box = layout.box().column(align=True)
            for i, line in enumerate(_wrap(warning, 44)):
                box.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')
        points = instances.points_object(coll)
        if points is not None:
            box = layout.box()
            box.label(text=f"{len(points.data.vertices)} instances", icon='OUTLINER_OB_POINTCLOUD')
            row = box.row(align=True)
            row.operator("jampacked.make_real", text="Make All Real").which = 'ALL'
            row.operator("jampacked.make_real", text="Selected Points").which = 'SELECTED'
            for t, name in enumerate(coll.get(summary.PREFIX + "type_names", [])):
                op = box.operator("jampacked.make_real", text=f"Make {name} Real")
                op.which, op.type_index = 'TYPE', t


class JAMPACKED_PT_export(_Sidebar, bpy.types.Panel):
    """Export settings and button."""

    bl_label = "Export"
    bl_parent_id = "JAMPACKED_PT_pack"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context: bpy.types.Context) -> None:
        s = context.scene.jampacked
        layout = self.layout
        unit = context.scene.unit_settings
        layout.label(text="Units: " + units.units_line(unit.system, unit.scale_length),
                     icon='DRIVER_DISTANCE')
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(s, "export_mode")
        if s.export_mode != 'PARTS':
            layout.prop(s, "shell")
            if s.shell > 0:
                layout.prop(s, "opening")
                if s.opening != 'NONE':
                    layout.prop(s, "opening_axis")
                    layout.prop(s, "opening_at" if s.opening == 'PLANE' else "opening_size")
                layout.prop(s, "drain")
        if s.export_mode == 'CONNECT':
            layout.prop(s, "connector")
        if s.export_mode != 'PARTS':
            layout.prop(s, "fill_voids")
        if s.export_mode == 'PARTS':
            layout.prop(s, "split_files")
        layout.prop(s, "resolution")
        layout.prop(s, "file_format")
        layout.prop(s, "filepath")
        layout.operator("jampacked.export", icon='EXPORT')


class JAMPACKED_PT_validate(_Sidebar, bpy.types.Panel):
    """Validate selected meshes and select what fails."""

    bl_label = "Validate"
    bl_parent_id = "JAMPACKED_PT_pack"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context: bpy.types.Context) -> None:
        s = context.scene.jampacked
        layout = self.layout
        row = layout.row(align=True)
        row.operator("jampacked.validate", icon='CHECKMARK')
        row.prop(s, "validate_modifiers", text="", icon='MODIFIER')
        layout.operator("jampacked.make_manifold", icon='MOD_MESHDEFORM')
        for report in context.window_manager.jampacked_validation.reports:
            box = layout.box()
            box.label(text=report.object_name, icon='CHECKMARK' if report.passed else 'ERROR')
            col = box.column(align=True)
            for line in _wrap(report.summary, 44):
                col.label(text=line)
            if report.note:
                col.label(text=report.note, icon='INFO')
            for check in report.checks:
                if check.count == 0 or check.kind in ("bodies",):
                    continue
                row = box.row(align=True)
                row.label(text=f"{check.label}: {check.count}")
                if check.selectable:
                    op = row.operator("jampacked.select_defects", text="",
                                      icon='RESTRICT_SELECT_OFF')
                    op.object_name = report.object_name
                    op.kind = check.kind


classes = (
    JAMPACKED_UL_types,
    JAMPACKED_PT_pack,
    JAMPACKED_PT_result,
    JAMPACKED_PT_export,
    JAMPACKED_PT_validate,
)
