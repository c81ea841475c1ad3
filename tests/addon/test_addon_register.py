"""Registering the add-on, and drawing its panels in every state."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("bpy")

from addon_helpers import Layout  # noqa: E402


def _registered(bpy) -> dict[str, bool]:
    return {
        "scene": hasattr(bpy.types.Scene, "jampacked"),
        "job": hasattr(bpy.types.WindowManager, "jampacked_job"),
        "pack": hasattr(bpy.types, "JAMPACKED_OT_pack"),
        "panel": hasattr(bpy.types, "JAMPACKED_PT_pack"),
        "list": hasattr(bpy.types, "JAMPACKED_UL_types"),
    }


def test_register_and_unregister_twice(bpy, addon):
    assert all(_registered(bpy).values())
    for _ in range(2):
        addon.unregister()
        assert not any(_registered(bpy).values())
        addon.register()
        assert all(_registered(bpy).values())
    handlers = [h for h in bpy.app.handlers.load_pre if h.__module__ == addon.__name__]
    assert len(handlers) == 1
    assert {c.bl_idname for c in addon.operators.classes} == {
        "jampacked.pack", "jampacked.export", "jampacked.cancel", "jampacked.type_add",
        "jampacked.type_remove", "jampacked.type_move", "jampacked.validate",
        "jampacked.select_defects", "jampacked.make_manifold", "jampacked.make_real"}


def _draw_all(bpy, addon) -> list:
    calls: list = []
    context = bpy.context
    for cls in addon.ui.classes:
        if not hasattr(cls, "draw"):
            continue
        if hasattr(cls, "poll") and not cls.poll(context):
            continue
        cls.draw(SimpleNamespace(layout=Layout(calls)), context)
    s = context.scene.jampacked
    for item in s.types:
        addon.ui.JAMPACKED_UL_types.draw_item(None, context, Layout(calls), s, item, 0, s,
                                              "active_type")
    return calls


def _labels(calls) -> list[str]:
    return [kw.get("text", "") for name, _args, kw in calls if name == "label"]


def test_panels_draw_in_every_state(bpy, addon, scene, tmp_path):
    s = scene.settings
    assert _draw_all(bpy, addon)  # idle, no result yet

    state = bpy.context.window_manager.jampacked_job
    state.running, state.title, state.fraction, state.message = True, "Packing", 0.42, \
        "phase 1: 3 placed, density 12%"
    calls = _draw_all(bpy, addon)
    assert any(name == "progress" for name, _a, _k in calls)
    assert "phase 1: 3 placed, density 12%" in _labels(calls)
    state.running = False

    assert bpy.ops.jampacked.pack() == {'FINISHED'}
    for mode in ('CONNECT', 'UNION', 'PARTS'):
        s.export_mode = mode
        s.shell, s.opening = 1.0, 'WINDOW'
        calls = _draw_all(bpy, addon)
    assert "Density" in _labels(calls) and "Certified" in _labels(calls)

    scene.box.select_set(True)
    bpy.ops.jampacked.validate()
    assert any("PASS" in text for text in _labels(_draw_all(bpy, addon)))
