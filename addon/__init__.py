"""jampacked for Blender: pack objects into a container mesh, export and validate prints.

A thin front end over the same engine and export as the ``jampacked`` command line: it reads
Blender objects as world-space arrays (:mod:`.bridge`), runs the engine in a worker thread
(:mod:`.worker`, :mod:`.engine`) followed by a modal timer (:mod:`.operators`) that draws
the placement as it grows (:mod:`.live_view`), and shows everything in the "Jampacked" tab
of the 3D viewport's sidebar (:mod:`.ui`). Settings live on the scene (:mod:`.props`).
Enabling it starts compiling the engine in the background (:func:`.worker.start_warm_up`).

A Blender extension (see ``blender_manifest.toml``): no ``bl_info``, relative imports; the
engine and its dependencies ship as wheels inside the extension's zip (``addon/build.py``).
"""

import bpy
from bpy.app.handlers import persistent

from . import live_view, operators, props, ui, worker

classes = (*props.classes, *operators.classes, *ui.classes)


#: seconds between panel redraws while the engine warms up
WARM_UP_REDRAW = 0.5


def _redraw_while_warming() -> float | None:
    """Timer: redraw the sidebar while the warm-up runs (its progress is in the panel)."""
    wm = getattr(bpy.context, "window_manager", None)
    for window in getattr(wm, "windows", ()):
        for area in (window.screen.areas if window.screen is not None else ()):
            if area.type == 'VIEW_3D':
                area.tag_redraw()
    snap = worker.warm_up_snapshot()
    return WARM_UP_REDRAW if snap is not None and snap.state == worker.RUNNING else None


@persistent
def _abandon_job(*_args: object) -> None:
    """A file is being loaded: stop the running job (its result would have nowhere to go)."""
    worker.abandon()


def register() -> None:
    """Register classes, properties and the file-load handler; start compiling the engine
    in the background (first run: tens of seconds; later runs load it from numba's cache)."""
    for cls in classes:
        bpy.utils.register_class(cls)
    props.register_properties()
    if _abandon_job not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(_abandon_job)
    worker.start_warm_up()
    if not bpy.app.timers.is_registered(_redraw_while_warming):
        bpy.app.timers.register(_redraw_while_warming, first_interval=WARM_UP_REDRAW,
                                persistent=True)


def unregister() -> None:
    """Undo :func:`register`; a running job is cancelled first."""
    worker.abandon(timeout=5.0)
    live_view.unregister()
    if bpy.app.timers.is_registered(_redraw_while_warming):
        bpy.app.timers.unregister(_redraw_while_warming)
    if _abandon_job in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_abandon_job)
    props.unregister_properties()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    operators.validation_cache().clear()
