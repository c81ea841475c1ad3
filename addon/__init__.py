"""jampacked for Blender: pack objects into a container mesh, export and validate prints.

A thin front end over the same engine and export as the ``jampacked`` command line: it reads
Blender objects as world-space arrays (:mod:`.bridge`), runs the engine in a worker thread
(:mod:`.worker`, :mod:`.engine`) followed by a modal timer (:mod:`.operators`), and shows
everything in the "Jampacked" tab of the 3D viewport's sidebar (:mod:`.ui`). Settings live
on the scene (:mod:`.props`).

A Blender extension (see ``blender_manifest.toml``): no ``bl_info``, relative imports; the
engine and its dependencies ship as wheels inside the extension's zip (``addon/build.py``).
"""

import bpy
from bpy.app.handlers import persistent

from . import operators, props, ui, worker

classes = (*props.classes, *operators.classes, *ui.classes)


@persistent
def _abandon_job(*_args: object) -> None:
    """A file is being loaded: stop the running job (its result would have nowhere to go)."""
    worker.abandon()


def register() -> None:
    """Register classes, properties and the file-load handler."""
    for cls in classes:
        bpy.utils.register_class(cls)
    props.register_properties()
    if _abandon_job not in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.append(_abandon_job)


def unregister() -> None:
    """Undo :func:`register`; a running job is cancelled first."""
    worker.abandon(timeout=5.0)
    if _abandon_job in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_abandon_job)
    props.unregister_properties()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    operators.validation_cache().clear()
