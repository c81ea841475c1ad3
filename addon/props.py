"""Settings and state of the add-on, as Blender properties.

- ``Scene.jampacked`` (:class:`JAMPACKED_PG_settings`): what to pack and how, export settings,
  and the result collection last made (saved with the .blend file, undone with the scene).
- ``WindowManager.jampacked_job`` (:class:`JAMPACKED_PG_job`): progress of the running
  job (not saved, not part of undo: it is UI state).
- ``WindowManager.jampacked_validation`` (:class:`JAMPACKED_PG_validation`): the last
  Validate results, one entry per object.

Lengths are in Blender units (the scene's world space), shown and typed in the scene's
units (with a unit system, "0.5 mm" typed into a length field is converted); Export writes
millimetres, converting with the scene's unit scale (:mod:`.units`).
"""

# No "from __future__ import annotations" here: Blender reads the property annotations
# as objects, not strings.
import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)

from .bridge import GEOMETRY_TYPES


def is_mesh_object(_self: bpy.types.PropertyGroup, obj: bpy.types.Object) -> bool:
    """Pointer poll: only objects with a surface (meshes, curves, text, surfaces, metaballs:
    Pack reads their evaluated mesh) can be picked as container or object type."""
    return obj.type in GEOMETRY_TYPES


class JAMPACKED_PG_type(bpy.types.PropertyGroup):
    """One object type: a mesh object and its target share (by count)."""

    object: PointerProperty(
        name="Object", type=bpy.types.Object, poll=is_mesh_object,
        description="Mesh object packed as this type, at its size in the scene "
                    "(modifiers applied)")
    share: FloatProperty(
        name="Share", default=1.0, min=0.0, soft_max=100.0,
        description="Target share of this type by count (relative: shares are normalised)")


FIDELITY_ITEMS = [
    ('AUTO', "Auto", "Chosen from the scene: fewer spheres when there are many objects"),
    ('LOW', "Low", "Fewest spheres and coarsest grids: fastest"),
    ('MEDIUM', "Medium", "Balanced"),
    ('HIGH', "High", "Most spheres: slowest, tightest contacts"),
]

MODE_ITEMS = [
    ('CONNECT', "Connect", "One body: floating objects tied in by struts"),
    ('UNION', "Union", "One watertight body where objects touch"),
    ('PARTS', "Parts", "One body per object, kept apart (printing clearance)"),
]

OPENING_ITEMS = [
    ('NONE', "None", "Closed shell"),
    ('PLANE', "Plane Cut", "Remove the shell beyond a plane so the objects show"),
    ('WINDOW', "Window", "Cut a round hole through one side of the shell"),
]

AXIS_ITEMS = [(a.upper().replace("+", "P").replace("-", "N"), a, f"Along {a}")
              for a in ("+x", "-x", "+y", "-y", "+z", "-z")]

RESULT_KIND_ITEMS = [
    ('AUTO', "Auto", "Instances from the threshold count on, objects below it"),
    ('OBJECTS', "Objects", "One object per placement (slow and heavy at tens of thousands)"),
    ('INSTANCES', "Instances", "One points object drawing every placement as an instance of "
                               "its type (Make Real turns the ones you want into objects)"),
]

#: placements from which an Auto result is instanced
INSTANCE_THRESHOLD = 2000

FORMAT_ITEMS = [
    ('STL', "STL", "Binary STL (one mesh)"),
    ('3MF', "3MF", "3MF (one object per body, millimetres)"),
    ('OBJ', "OBJ", "Wavefront OBJ"),
    ('PLY', "PLY", "Binary PLY"),
]


#: Blender 4.5 warns on '//' paths in a FILE_PATH property unless it declares that it takes
#: them; older versions do not know the option (the manifest allows 4.2)
BLEND_RELATIVE = ({"options": {'PATH_SUPPORTS_BLEND_RELATIVE'}}
                  if bpy.app.version >= (4, 5, 0) else {})


def axis_name(identifier: str) -> str:
    """'PZ' -> '+z' (enum identifiers cannot hold '+' or '-')."""
    return ("+" if identifier[0] == "P" else "-") + identifier[1].lower()


class JAMPACKED_PG_settings(bpy.types.PropertyGroup):
    """Scene settings: inputs of Pack and Export, and the last result."""

    container: PointerProperty(
        name="Container", type=bpy.types.Object, poll=is_mesh_object,
        description="Closed mesh to fill (modifiers applied, in world space)")
    types: CollectionProperty(type=JAMPACKED_PG_type, name="Object Types")
    active_type: IntProperty(name="Active Type", default=0, min=0)
    seed: IntProperty(name="Seed", default=0, min=0,
                      description="Random seed: same inputs and seed, same packing")
    clearance: FloatProperty(
        name="Clearance", default=0.0, min=0.0, soft_max=10.0, subtype='DISTANCE',
        unit='LENGTH', precision=3,
        description="Minimum gap between objects and to the wall, in scene units (type "
                    "e.g. '0.3 mm' to give millimetres; 0: objects may touch)")
    fidelity: EnumProperty(name="Fidelity", items=FIDELITY_ITEMS, default='AUTO',
                           description="Resolution of the object approximations")
    mix_tolerance: FloatProperty(
        name="Mix Tolerance", default=0.04, min=0.0, max=1.0, precision=3, step=1,
        description="How far the type mix may drift from the shares (total variation "
                    "distance) for the cavity passes to fill small holes: a tight mix can leave "
                    "holes unfilled (0: the mix as close as the count allows)")
    time_budget: FloatProperty(
        name="Time Budget", default=60.0, min=0.0, soft_max=600.0, subtype='TIME_ABSOLUTE',
        unit='TIME_ABSOLUTE',
        description="Seconds of placement before the best packing so far is kept "
                    "(0: no limit); certification runs after it")
    keep_previous: BoolProperty(
        name="Keep Previous", default=False,
        description="Keep the earlier results of this container: without it a Pack "
                    "replaces the last result (one undo brings it back)")
    result_kind: EnumProperty(
        name="Result As", items=RESULT_KIND_ITEMS, default='AUTO',
        description="How Pack adds the placements to the scene")
    instance_threshold: IntProperty(
        name="Instances From", default=INSTANCE_THRESHOLD, min=1, soft_max=100000,
        description="Auto: a packing with at least this many objects is added as instances")
    result: PointerProperty(
        name="Result", type=bpy.types.Collection,
        description="Collection made by the last Pack: the Result panel shows it and "
                    "Export writes it, unless the active object is in another result")

    # export
    export_mode: EnumProperty(name="Mode", items=MODE_ITEMS, default='CONNECT')
    shell: FloatProperty(
        name="Shell", default=0.0, min=0.0, soft_max=10.0, subtype='DISTANCE',
        unit='LENGTH', precision=3,
        description="Least wall thickness of the container shell (0: no shell)")
    opening: EnumProperty(name="Opening", items=OPENING_ITEMS, default='NONE')
    opening_axis: EnumProperty(name="Axis", items=AXIS_ITEMS, default='PZ',
                               description="Side of the container the opening faces")
    opening_at: FloatProperty(
        name="At", default=0.75, min=0.01, max=0.99, subtype='FACTOR',
        description="Plane position as a fraction of the container's extent along the axis")
    opening_size: FloatProperty(
        name="Diameter", default=10.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
        description="Window diameter")
    drain: FloatProperty(
        name="Drain", default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
        description="Diameter of a drainage hole at the shell's lowest point (0: none)")
    connector: FloatProperty(
        name="Connector", default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
        description="Strut diameter in Connect mode (0: 0.2 x the smallest object's "
                    "equivalent diameter)")
    resolution: FloatProperty(
        name="Resolution", default=0.0, min=0.0, subtype='DISTANCE', unit='LENGTH',
        precision=3,
        description="Simplify meshes to this tolerance, e.g. the printer's resolution "
                    "(0: keep every triangle)")
    fill_voids: BoolProperty(
        name="Fill Sealed Voids", default=True,
        description="Union and Connect: fill pockets shut in between objects, struts and "
                    "shell, which resin and powder prints cannot drain (a closed shell keeps "
                    "its cavity)")
    split_files: BoolProperty(
        name="One File per Part", default=False,
        description="Parts mode: write one file per part instead of one file")
    filepath: StringProperty(
        name="File", default="//jampacked.stl", subtype='FILE_PATH', **BLEND_RELATIVE,
        description="Output file ('//' is the .blend file's folder); the extension follows "
                    "the format")
    file_format: EnumProperty(name="Format", items=FORMAT_ITEMS, default='STL')
    validate_modifiers: BoolProperty(
        name="Apply Modifiers", default=True,
        description="Validate meshes with their modifiers applied (selecting offending "
                    "elements needs modifiers that keep the topology)")


class JAMPACKED_PG_job(bpy.types.PropertyGroup):
    """Progress of the running job, copied from the worker thread by the modal timer."""

    running: BoolProperty(name="Running", default=False)
    title: StringProperty(name="Job")
    fraction: FloatProperty(name="Progress", default=0.0, min=0.0, max=1.0, subtype='FACTOR')
    message: StringProperty(name="Message")
    stopping: BoolProperty(name="Stopping", default=False)
    last_message: StringProperty(
        name="Last Message", description="Outcome of the last Pack or Export")
    last_level: StringProperty(name="Last Level", default='INFO')


class JAMPACKED_PG_check(bpy.types.PropertyGroup):
    """One kind of defect found by Validate: its kind (an offending-index key) and count."""

    kind: StringProperty(name="Kind")
    label: StringProperty(name="Label")
    count: IntProperty(name="Count")
    selectable: BoolProperty(name="Selectable", default=False)


class JAMPACKED_PG_object_report(bpy.types.PropertyGroup):
    """Validation of one object."""

    object_name: StringProperty(name="Object")
    passed: BoolProperty(name="Passed")
    summary: StringProperty(name="Summary")
    note: StringProperty(name="Note")
    checks: CollectionProperty(type=JAMPACKED_PG_check)


class JAMPACKED_PG_validation(bpy.types.PropertyGroup):
    """The last Validate run."""

    reports: CollectionProperty(type=JAMPACKED_PG_object_report)


classes = (
    JAMPACKED_PG_type,
    JAMPACKED_PG_settings,
    JAMPACKED_PG_job,
    JAMPACKED_PG_check,
    JAMPACKED_PG_object_report,
    JAMPACKED_PG_validation,
)


def register_properties() -> None:
    """Attach the property groups to Scene and WindowManager (after registering classes)."""
    bpy.types.Scene.jampacked = PointerProperty(type=JAMPACKED_PG_settings)
    bpy.types.WindowManager.jampacked_job = PointerProperty(type=JAMPACKED_PG_job)
    bpy.types.WindowManager.jampacked_validation = PointerProperty(type=JAMPACKED_PG_validation)


def unregister_properties() -> None:
    """Detach what :func:`register_properties` attached."""
    del bpy.types.WindowManager.jampacked_validation
    del bpy.types.WindowManager.jampacked_job
    del bpy.types.Scene.jampacked
