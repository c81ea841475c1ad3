"""Operators: Pack, Cancel, Export, Validate, Select Defects and the type list buttons.

Pack and Export run their job in a worker thread (:mod:`.worker`) and follow it with a modal
timer (:class:`JobRunner`): progress goes to ``WindowManager.jampacked_job`` (the panel) and
the status bar; Esc or the Cancel button stop it. With no user interface (background mode,
or ``execute`` from a script) the same steps run in a blocking loop. The scene is only
changed at the end, in the step that returns FINISHED, so Pack is one undo step and a
cancelled or failed job leaves the scene as it was.
"""

# No "from __future__ import annotations": Blender reads operator property annotations.
import contextlib
import time
from collections.abc import Iterator
from typing import Any

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty

from . import bridge, engine, instances, live_view, repair, results, summary, worker
from .props import axis_name

#: seconds between progress updates
POLL_SECONDS = 0.1


def _errors() -> Any:
    from jampacked.core import errors

    return errors


def _tag_redraw(context: bpy.types.Context) -> None:
    wm = context.window_manager
    for window in getattr(wm, "windows", ()):
        screen = window.screen
        for area in (screen.areas if screen is not None else ()):
            if area.type in {'VIEW_3D', 'STATUSBAR'}:
                area.tag_redraw()


def _status(context: bpy.types.Context, text: str | None) -> None:
    workspace = getattr(context, "workspace", None)
    if workspace is not None:
        try:
            workspace.status_text_set(text)
        except (AttributeError, RuntimeError, TypeError):
            pass


class JobRunner:
    """Runs a :class:`worker.Job` from an operator: modal timer in the UI, blocking loop
    otherwise. Plain Python (no bpy base class), so tests can drive ``modal`` directly.

    Subclasses implement ``make_job(context) -> worker.Job`` (main thread: read the scene,
    raise JampackedError on bad input) and ``apply(context, result) -> set`` (main thread:
    change the scene, report, return {'FINISHED'}). ``report`` comes from bpy's Operator.
    """

    # plain class attributes, not annotations: Blender reads annotations as properties
    job_title = "Job"
    _job = None  # the worker.Job being followed
    _timer = None  # the window manager timer of the modal UI
    _log = None  # a worker.ProgressLog: progress lines on stdout (background mode)
    _notes_shown = 0  # the job's notes (worker.Snapshot.notes) already reported

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        """One job at a time (shared by every operator that runs a job)."""
        if worker.busy():
            cls.poll_message_set("A Jampacked job is running")
            return False
        return context.scene is not None

    # ---------------------------------------------------------------- to implement
    def make_job(self, context: bpy.types.Context) -> worker.Job:
        raise NotImplementedError

    def apply(self, context: bpy.types.Context, result: Any) -> set[str]:
        raise NotImplementedError

    def on_start(self, context: bpy.types.Context) -> None:
        """Main thread, once the job runs (the live view starts here)."""

    def on_poll(self, context: bpy.types.Context, job: worker.Job) -> None:
        """Main thread, at every poll while the job runs."""

    def on_end(self, context: bpy.types.Context) -> None:
        """Main thread, once, on every way out (done, cancelled, failed, an exception)."""

    # ---------------------------------------------------------------- steps
    def begin(self, context: bpy.types.Context) -> bool:
        """Check, read the inputs and start the job; False (after a report) if it cannot."""
        missing = engine.engine_missing()
        if missing:
            self._fail(context, missing)
            return False
        if worker.busy():
            job = worker.active_job()
            self._fail(context, f"{job.title if job else 'a job'} is still running: wait "
                                "for it or cancel it (Esc, or Cancel in the Jampacked panel).")
            return False
        try:
            job = self.make_job(context)
            self._job = job.start()
            self._notes_shown = 0
        except (_errors().JampackedError, worker.BusyError) as exc:
            self._fail(context, str(exc))
            return False
        state = context.window_manager.jampacked_job
        state.running = True
        state.title = job.title
        state.fraction = 0.0
        state.message = "starting"
        state.stopping = False
        self.on_start(context)
        return True

    def step(self, context: bpy.types.Context) -> set[str]:
        """One poll: copy progress to the UI; when the job is over, handle its outcome.

        Returns {'RUNNING_MODAL'} while it runs, then {'FINISHED'} or {'CANCELLED'}.
        """
        job = self._job
        if job is None:
            return {'CANCELLED'}
        snap = job.snapshot()
        state = context.window_manager.jampacked_job
        state.fraction = snap.fraction
        state.message = snap.message
        state.stopping = snap.stopping
        for advice in snap.notes[self._notes_shown:]:  # e.g. a large scene without a budget
            self._note(context, 'WARNING', summary.in_blender_words(advice))
        self._notes_shown = len(snap.notes)
        if snap.state == worker.RUNNING:
            self.on_poll(context, job)
            line = self._log.line(snap) if self._log is not None else None
            if line:
                print(line, flush=True)
            hint = "stopping..." if snap.stopping else "Esc to cancel"
            _status(context, f"Jampacked {job.title.lower()}: {snap.fraction:.0%} "
                             f"{snap.message} ({hint})")
            _tag_redraw(context)
            return {'RUNNING_MODAL'}
        self.end(context)
        if snap.state == worker.CANCELLED:
            what = ("finished before anything was done, so there was nothing to keep"
                    if job.finish_requested else "cancelled")
            self._note(context, 'WARNING', f"{job.title} {what}: nothing was changed.")
            return {'CANCELLED'}
        if snap.state == worker.FAILED:
            self._fail(context, job.error or f"{job.title} failed.")
            return {'CANCELLED'}
        try:
            return self.apply(context, job.result)
        except _errors().JampackedError as exc:
            self._fail(context, str(exc))
        except Exception as exc:  # noqa: BLE001 - shown to the user; the scene is restored
            import traceback

            traceback.print_exc()
            self._fail(context, f"{job.title} could not add its result ({type(exc).__name__}: "
                                f"{exc}); nothing was changed.")
        return {'CANCELLED'}

    def end(self, context: bpy.types.Context) -> None:
        """Remove the timer, clear the status bar, free the job slot."""
        wm = context.window_manager
        try:
            if self._timer is not None:
                wm.event_timer_remove(self._timer)
                self._timer = None
            _status(context, None)
            wm.jampacked_job.running = False
            wm.jampacked_job.stopping = False
            _tag_redraw(context)
        finally:
            try:
                self.on_end(context)
            finally:
                if self._job is not None:
                    self._job.release()

    def run_blocking(self, context: bpy.types.Context) -> set[str]:
        """The modal steps in a loop, for scripts and background mode.

        Any exit but the job's own end (Ctrl-C's KeyboardInterrupt while waiting, an
        exception in a step) cancels the job and frees its slot before it propagates.
        """
        if not self.begin(context):
            return {'CANCELLED'}
        if bpy.app.background:  # no panel or status bar to watch: print the progress
            self._log = worker.ProgressLog(self._job.title)
        with self.guard(context):
            while True:
                result = self.step(context)
                if result != {'RUNNING_MODAL'}:
                    return result
                self._job.wait(POLL_SECONDS)
        return {'CANCELLED'}  # not reached: the loop returns or the guard re-raises

    @contextlib.contextmanager
    def guard(self, context: bpy.types.Context) -> Iterator[None]:
        """Cancel the job and free the slot if the block is left by an exception."""
        try:
            yield
        except BaseException:
            if self._job is not None:
                self._job.cancel()
            self.end(context)
            raise

    # ---------------------------------------------------------------- operator API
    def execute(self, context: bpy.types.Context) -> set[str]:
        return self.run_blocking(context)

    def invoke(self, context: bpy.types.Context, event: Any) -> set[str]:
        if bpy.app.background or context.window is None:
            return self.run_blocking(context)
        if not self.begin(context):
            return {'CANCELLED'}
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_SECONDS, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context: bpy.types.Context, event: Any) -> set[str]:
        with self.guard(context):
            if event.type == 'ESC' and event.value == 'PRESS':
                if self._job is not None:
                    self._job.cancel()
                return self.step(context)
            if event.type == 'TIMER':
                return self.step(context)
            return {'PASS_THROUGH'}
        return {'CANCELLED'}  # not reached

    def cancel(self, context: bpy.types.Context) -> None:
        """Called by Blender when the modal operator is ended from outside (file load)."""
        if self._job is not None:
            self._job.cancel()
        self.end(context)

    # ---------------------------------------------------------------- messages
    def _note(self, context: bpy.types.Context, level: str, message: str) -> None:
        note(self, context, level, message)

    def _fail(self, context: bpy.types.Context, message: str) -> None:
        self._note(context, 'ERROR', summary.in_blender_words(message))


class PackRunner(JobRunner):
    """Pack: read the scene, pack in the thread, add the result collection."""

    job_title = "Packing"
    _request = None  # the bridge.PackRequest the job was made from

    def make_job(self, context: bpy.types.Context) -> worker.Job:
        request = bridge.gather_pack(context)
        self._request = request

        def run(progress: worker.Progress, should_cancel: worker.ShouldCancel) -> Any:
            return engine.pack_triangles(
                request.container, request.types, request.shares, seed=request.seed,
                clearance=request.clearance, fidelity=request.fidelity,
                time_budget=request.time_budget, mix_tolerance=request.mix_tolerance,
                progress=progress, should_cancel=should_cancel, snapshot=job.publish)

        job = worker.Job(self.job_title, run)
        return job

    def on_start(self, context: bpy.types.Context) -> None:
        live_view.VIEW.start()

    def on_poll(self, context: bpy.types.Context, job: worker.Job) -> None:
        live_view.VIEW.update(job.placed())  # the runner tags the viewports for redraw

    def on_end(self, context: bpy.types.Context) -> None:
        live_view.VIEW.stop()

    def apply(self, context: bpy.types.Context, result: engine.PackOutcome) -> set[str]:
        if result.packing.n == 0 and result.packing.report.stopped == "cancelled":
            # an empty result is none: it would replace the previous one (as the command
            # line keeps its output files)
            self._note(context, 'WARNING', "Packing finished before any object was placed, "
                                           "so there was nothing to keep: nothing was "
                                           "changed.")
            return {'CANCELLED'}
        bridge.check_unchanged(context, self._request)
        last = context.scene.jampacked.result
        coll = bridge.build_result(context, self._request, result)
        # an earlier result holding an input (a placed object picked as a type) is kept
        kept = 0
        if context.scene.jampacked.keep_previous:
            coll[results.KEPT] = True
        elif not bridge.inputs_in_results(context.scene, self._request):
            kept = results.replace_previous(context.scene, coll, last)
        results.make_shown(context, coll)
        p = result.packing
        m, cert = p.metrics, p.certificate
        nni = m.get("nni_mean")
        text = (f"Packed {p.n} objects into '{coll.name}': density {m.get('density', 0):.1%}, "
                f"TVD {m.get('tvd', 0):.3f}, NNI {'-' if nni is None else f'{nni:.2f}'}, "
                f"{'certified' if cert.get('certified') else 'NOT certified'}.")
        if kept:
            text += (f" Kept {kept} object(s) or collection(s) you had put in the previous "
                     f"result, now in '{coll.name}'.")
        warned = summary.warnings(coll)
        for w in warned:  # each in the Info log; the panel's Result shows them all
            self.report({'WARNING'}, w)
        if warned:
            text += f" {len(warned)} warning(s): see Result in the panel."
        self._note(context, 'INFO' if cert.get("certified") and not warned else 'WARNING',
                   text)
        return {'FINISHED'}


class JAMPACKED_OT_pack(PackRunner, bpy.types.Operator):
    """Fill the container with the object types (runs in the background; Esc cancels)"""

    bl_idname = "jampacked.pack"
    bl_label = "Pack"
    bl_options = {'REGISTER', 'UNDO'}


class ExportRunner(JobRunner):
    """Export: read the result and meshes, export in the thread, report the validation."""

    job_title = "Export"

    def _fail(self, context: bpy.types.Context, message: str) -> None:
        self._note(context, 'ERROR', summary.export_in_mm(summary.in_blender_words(message)))

    def make_job(self, context: bpy.types.Context) -> worker.Job:
        s = context.scene.jampacked
        options = engine.export_options(
            s.export_mode, s.shell, s.opening, axis_name(s.opening_axis), s.opening_at,
            s.opening_size, s.drain, s.connector, s.resolution, s.split_files,
            s.fill_voids)
        if context.object is not None and context.object.mode == 'EDIT':
            # Edit Mode's points and meshes reach their data only in Object Mode
            bpy.ops.object.mode_set(mode='OBJECT')
        request = bridge.gather_export(context, options)
        self._collection = request.collection

        def run(progress: worker.Progress, should_cancel: worker.ShouldCancel) -> Any:
            result = engine.export_triangles(
                request.packing_json, request.container, request.types, request.out_path,
                request.options, progress=progress, should_cancel=should_cancel,
                scale=request.scale, placements=request.placements)
            if request.placements is not None and request.placements.removed_only:
                result.warnings.append(
                    f"exported the {len(request.placements.labels)} objects the result holds "
                    "now; the others were removed since Pack, and the rest is as certified")
            if request.left_out:
                result.warnings.append(
                    f"left out, as no objects of the packing (their mesh is none of its "
                    f"types'): {', '.join(repr(n) for n in request.left_out[:5])}"
                    + (f" and {len(request.left_out) - 5} more" if len(request.left_out) > 5
                       else ""))
            return result

        return worker.Job(self.job_title, run)

    def apply(self, context: bpy.types.Context, result: Any) -> set[str]:
        lines = [summary.export_in_mm(v.summary()) for v in result.validation]
        text = summary.in_blender_words(
            f"Exported '{self._collection}' to {', '.join(result.paths)}: "
            f"{result.summary('mm')}")
        if lines:
            text += " " + " ".join(lines)
        text += "".join(f" Warning: {summary.export_in_mm(summary.in_blender_words(w))}"
                        for w in result.warnings)
        level = 'INFO' if result.passed and not result.warnings else 'WARNING'
        self._note(context, level, text)
        return {'FINISHED'}


class JAMPACKED_OT_export(ExportRunner, bpy.types.Operator):
    """Export the packing as a printable mesh and validate the file written"""

    bl_idname = "jampacked.export"
    bl_label = "Export"
    bl_options = {'REGISTER'}


class JAMPACKED_OT_cancel(bpy.types.Operator):
    """Stop the running Jampacked job"""

    bl_idname = "jampacked.cancel"
    bl_label = "Cancel"
    bl_options = {'INTERNAL'}

    action: EnumProperty(
        name="Action",
        items=[('CANCEL', "Cancel", "Stop and discard: the scene stays as it was"),
               ('FINISH', "Finish Now", "Stop placing and keep the best certified packing "
                                        "so far")],
        default='CANCEL')

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return worker.busy()

    def execute(self, context: bpy.types.Context) -> set[str]:
        job = worker.active_job()
        if job is None:
            return {'CANCELLED'}
        if self.action == 'FINISH':
            job.finish_early()
        else:
            job.cancel()
        context.window_manager.jampacked_job.stopping = True
        return {'FINISHED'}


def note(op: bpy.types.Operator, context: bpy.types.Context, level: str, message: str
         ) -> None:
    """Report a message and keep it as the panel's last one."""
    state = context.window_manager.jampacked_job
    state.last_message = message
    state.last_level = level
    op.report({level}, message)


class JAMPACKED_OT_make_real(bpy.types.Operator):
    """Turn instances of the packing into real objects sharing the type meshes (all, the
    points selected in Edit Mode, or one type)"""

    bl_idname = "jampacked.make_real"
    bl_label = "Make Real"
    bl_options = {'REGISTER', 'UNDO'}

    which: EnumProperty(
        name="Which",
        items=[('ALL', "All", "Every instance of the result"),
               ('SELECTED', "Selected Points", "The points selected in Edit Mode on the "
                                               "result's instances object"),
               ('TYPE', "One Type", "The instances of one object type")],
        default='ALL')
    type_index: IntProperty(name="Type", default=0, min=0,
                            description="One Type: the type's row (0 = the first type)")

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        coll = results.shown_result(context) if context.scene else None
        if coll is None or instances.points_object(coll) is None:
            cls.poll_message_set("The result shown (the active object's, else the last "
                                 "Pack's) has no instances")
            return False
        return not worker.busy()

    def execute(self, context: bpy.types.Context) -> set[str]:
        try:
            coll = bridge.result_collection(context)
            if context.object is not None and context.object.mode == 'EDIT':
                bpy.ops.object.mode_set(mode='OBJECT')  # the points' selection is saved
            made = bridge.make_real(coll, self.which, self.type_index)
        except _errors().JampackedError as exc:
            note(self, context, 'ERROR', str(exc)[:1].upper() + str(exc)[1:])
            return {'CANCELLED'}
        for obj in context.selected_objects:
            obj.select_set(False)
        for obj in made:
            obj.select_set(True)
        context.view_layer.objects.active = made[-1]
        points = instances.points_object(coll)
        left = len(points.data.vertices) if points is not None else 0
        note(self, context, 'INFO', f"Made {len(made)} object(s) real in '{coll.name}'; "
                                    f"{left} instance(s) left.")
        return {'FINISHED'}


# ------------------------------------------------------------------------------ type list


def _article(word: str) -> str:
    return "an" if word[:1] in "aeiou" else "a"


class JAMPACKED_OT_type_add(bpy.types.Operator):
    """Add the selected mesh objects (or curves, text, surfaces, metaballs) as object types
    (or an empty row)"""

    bl_idname = "jampacked.type_add"
    bl_label = "Add Object Type"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context: bpy.types.Context) -> set[str]:
        s = context.scene.jampacked
        listed = {item.object for item in s.types if item.object is not None}
        added, skipped = 0, []
        for obj in context.selected_objects:
            if obj in listed:
                skipped.append(f"'{obj.name}' is listed already")
            elif obj == s.container:
                skipped.append(f"'{obj.name}' is the container")
            elif obj.type not in bridge.GEOMETRY_TYPES:
                what = ("a collection instance: make it real first (Object > Apply > Make "
                        "Instances Real)" if obj.instance_type == 'COLLECTION'
                        else f"{_article(obj.type.lower())} {obj.type.lower()}, which has no "
                        "surface")
                skipped.append(f"'{obj.name}' is {what}")
            else:
                s.types.add().object = obj
                added += 1
        if skipped:
            self.report({'WARNING'}, "Not added: " + "; ".join(skipped) + ".")
            if not added:  # no empty row for a selection that gave nothing
                return {'CANCELLED'}
        if not added:  # nothing selected: an empty row to pick an object into
            s.types.add()
        s.active_type = len(s.types) - 1
        return {'FINISHED'}


class JAMPACKED_OT_type_remove(bpy.types.Operator):
    """Remove the active object type"""

    bl_idname = "jampacked.type_remove"
    bl_label = "Remove Object Type"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return len(context.scene.jampacked.types) > 0

    def execute(self, context: bpy.types.Context) -> set[str]:
        s = context.scene.jampacked
        s.types.remove(s.active_type)
        s.active_type = min(s.active_type, max(len(s.types) - 1, 0))
        return {'FINISHED'}


class JAMPACKED_OT_type_move(bpy.types.Operator):
    """Move the active object type up or down"""

    bl_idname = "jampacked.type_move"
    bl_label = "Move Object Type"
    bl_options = {'REGISTER', 'UNDO'}

    direction: EnumProperty(items=[('UP', "Up", ""), ('DOWN', "Down", "")], default='UP')

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return len(context.scene.jampacked.types) > 1

    def execute(self, context: bpy.types.Context) -> set[str]:
        s = context.scene.jampacked
        i = s.active_type
        j = i - 1 if self.direction == 'UP' else i + 1
        if 0 <= j < len(s.types):
            s.types.move(i, j)
            s.active_type = j
        return {'FINISHED'}


# ------------------------------------------------------------------------------ validate

#: object name -> (triangles, report, position groups, selectable) of the last Validate
_validation_cache: dict[str, tuple[Any, Any, np.ndarray, bool]] = {}


def validation_cache() -> dict[str, tuple[Any, Any, np.ndarray, bool]]:
    """The offending elements of the last Validate, by object name."""
    return _validation_cache


class JAMPACKED_OT_validate(bpy.types.Operator):
    """Check the selected meshes as 'jampacked validate' checks a file: closed, manifold,
    outward, no degenerate, duplicate or intersecting faces"""

    bl_idname = "jampacked.validate"
    bl_label = "Validate"
    bl_options = {'REGISTER', 'UNDO'}  # it may change the selection and enter edit mode

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return bool(_mesh_targets(context))

    def execute(self, context: bpy.types.Context) -> set[str]:
        missing = engine.engine_missing()
        if missing:
            note(self, context, 'ERROR', missing)
            return {'CANCELLED'}
        objects = _mesh_targets(context)
        apply_modifiers = context.scene.jampacked.validate_modifiers
        if apply_modifiers:
            try:
                for obj in objects:
                    bridge.require_evaluated(obj, "Object", context.view_layer, "Validate")
            except _errors().JampackedError as exc:
                note(self, context, 'ERROR', f"{exc} Or turn off Apply Modifiers to check "
                                             "its mesh as stored.")
                return {'CANCELLED'}
        bridge.flush_edit_mode(context)
        depsgraph = context.evaluated_depsgraph_get()
        results = context.window_manager.jampacked_validation.reports
        results.clear()
        _validation_cache.clear()
        failed = 0
        t0 = time.perf_counter()
        for obj in objects:
            tris = bridge.object_triangles(obj, depsgraph, apply_modifiers=apply_modifiers,
                                           outward=True)
            report = engine.validate_triangles(tris)
            selectable = (tris.n_polygons == len(obj.data.polygons)
                          and len(tris.vertices) == len(obj.data.vertices))
            _validation_cache[obj.name] = (tris, report, engine.position_groups(tris.vertices),
                                           selectable)
            entry = results.add()
            entry.object_name = obj.name
            entry.passed = report.passed
            entry.summary = report.summary().replace("mesh", obj.name, 1)
            if not selectable:
                entry.note = ("Modifiers change the topology: turn off Apply Modifiers to "
                              "select offending elements")
            for kind, label, count in engine.validation_counts(report):
                check = entry.checks.add()
                check.kind, check.label, check.count = kind, label, count
                check.selectable = selectable and kind in bridge.SELECTABLE_KINDS
            failed += not report.passed
        seconds = time.perf_counter() - t0
        shown = _select_failing(context, objects)
        # the panel's status line follows (an earlier Export's error no longer stands there)
        if failed:
            note(self, context, 'WARNING', f"{failed} of {len(objects)} mesh(es) fail: "
                 + "; ".join(r.summary for r in results if not r.passed))
        else:
            note(self, context, 'INFO', f"{len(objects)} mesh(es) pass ({seconds:.1f} s): "
                 + "; ".join(r.summary for r in results))
        if shown:
            self.report({'INFO'}, f"Selected {shown[1]} offending element(s) of "
                                  f"'{shown[0]}' in edit mode.")
        return {'FINISHED'}


def _select_failing(context: bpy.types.Context, objects: list[bpy.types.Object]
                    ) -> tuple[str, int] | None:
    """After Validate: select every offending element of the checked object that failed (the
    active one, else the first) in edit mode. Returns (object name, elements) or None when no
    failing object can show its elements (modifiers change the topology, not in the view
    layer)."""
    active = context.active_object
    for obj in sorted(objects, key=lambda o: o != active):
        cached = _validation_cache.get(obj.name)
        if cached is None or cached[1].passed or not cached[3]:
            continue
        if context.view_layer.objects.get(obj.name) is None:
            continue
        tris, report, groups, _ = cached
        offending = {k: v for k, v in report.offending.items()
                     if k in bridge.SELECTABLE_KINDS and len(v)}
        if not offending:
            continue
        return obj.name, bridge.select_offending(context, obj, offending, tris, groups)
    return None


class JAMPACKED_OT_select_defects(bpy.types.Operator):
    """Select the offending elements in edit mode"""

    bl_idname = "jampacked.select_defects"
    bl_label = "Select"
    bl_options = {'REGISTER', 'UNDO'}

    object_name: StringProperty(name="Object")
    kind: StringProperty(name="Kind")

    def execute(self, context: bpy.types.Context) -> set[str]:
        cached = _validation_cache.get(self.object_name)
        obj = bpy.data.objects.get(self.object_name)
        if cached is None or obj is None or obj.type != 'MESH':
            self.report({'ERROR'}, f"No validation of '{self.object_name}': run Validate "
                                   "first.")
            return {'CANCELLED'}
        tris, report, groups, selectable = cached
        if not selectable:
            self.report({'ERROR'}, f"'{obj.name}' was validated with modifiers that change "
                                   "its topology: turn off Apply Modifiers and validate again.")
            return {'CANCELLED'}
        if self.kind not in report.offending:
            self.report({'ERROR'}, f"Unknown kind of defect '{self.kind}'.")
            return {'CANCELLED'}
        if context.view_layer.objects.get(obj.name) is None:
            self.report({'ERROR'}, f"'{obj.name}' is not in the current view layer.")
            return {'CANCELLED'}
        try:
            count = bridge.select_offending(context, obj,
                                            {self.kind: report.offending[self.kind]}, tris,
                                            groups)
        except _errors().JampackedError as exc:
            self.report({'ERROR'}, str(exc))
            return {'CANCELLED'}
        label = dict((k, lab) for k, lab, _ in engine.validation_counts(report)).get(
            self.kind, self.kind)
        self.report({'INFO'}, f"Selected {count} element(s): {label.lower()} of '{obj.name}'.")
        return {'FINISHED'}


class JAMPACKED_OT_make_manifold(bpy.types.Operator):
    """Repair the selected meshes safely: merge vertices by distance, fill holes and
    recalculate normals outward (the mesh data, not its modifiers)"""

    bl_idname = "jampacked.make_manifold"
    bl_label = "Make Manifold"
    bl_options = {'REGISTER', 'UNDO'}

    merge_distance: FloatProperty(
        name="Merge Distance", default=0.0001, min=0.0, soft_max=1.0, precision=5,
        subtype='DISTANCE', unit='LENGTH',
        description="Vertices closer than this (scene units) are merged into one")

    @classmethod
    def poll(cls, context: bpy.types.Context) -> bool:
        return bool(_mesh_targets(context))

    def execute(self, context: bpy.types.Context) -> set[str]:
        objects = _mesh_targets(context)
        in_edit = context.object is not None and context.object.mode == 'EDIT'
        if in_edit:
            bpy.ops.object.mode_set(mode='OBJECT')
        done = []
        for mesh in {o.data for o in objects}:
            done.append(f"'{mesh.name}': "
                        f"{repair.make_manifold(mesh, self.merge_distance).summary()}")
        if in_edit:
            bpy.ops.object.mode_set(mode='EDIT')
        # the last Validate no longer describes these meshes
        context.window_manager.jampacked_validation.reports.clear()
        _validation_cache.clear()
        note(self, context, 'INFO', "Made manifold: " + "; ".join(done) + ". Validate again "
             "to check.")
        return {'FINISHED'}


def _mesh_targets(context: bpy.types.Context) -> list[bpy.types.Object]:
    """The selected mesh objects, or the active one if none is selected."""
    objects = [o for o in context.selected_objects if o.type == 'MESH']
    active = context.active_object
    if not objects and active is not None and active.type == 'MESH':
        objects = [active]
    return objects


classes = (
    JAMPACKED_OT_pack,
    JAMPACKED_OT_export,
    JAMPACKED_OT_cancel,
    JAMPACKED_OT_make_real,
    JAMPACKED_OT_type_add,
    JAMPACKED_OT_type_remove,
    JAMPACKED_OT_type_move,
    JAMPACKED_OT_validate,
    JAMPACKED_OT_select_defects,
    JAMPACKED_OT_make_manifold,
)

__all__ = ["ExportRunner", "JobRunner", "PackRunner", "classes", "validation_cache"]
