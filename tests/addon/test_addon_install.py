"""Installing the built zip through Blender's own extension system, headless.

Each install runs in a fresh Python process (Blender as the bpy module) with its user folders
in a temporary folder, so the session's registered add-on is not disturbed.

- The add-on-only zip (``build.py --no-wheels``) is installed and enabled here: it checks
  the manifest and package as Blender reads them, in a few seconds.
- The full zip with its wheels is tested only with ``pytest --wheels`` (see
  tests/conftest.py), and ``JAMPACKED_BARE_BLENDER_PYTHON`` must name a Python that has
  nothing but ``bpy`` and ``numpy<2`` installed (so that the engine can only come from the
  zip's wheels): it installs the linux-x64 zip (about 100 MB; wheels
  downloaded into addon/wheels/ unless there already), packs a small scene and exports it
  with a shell. It takes a minute or more (numba compiles the engine's kernels on first use),
  hence opt-in.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from addon_helpers import load_standalone

pytest.importorskip("bpy")

build = load_standalone("build")

SCRIPT = r'''
import json, os, sys, tempfile, time
import bpy

zip_path, mode = sys.argv[1], sys.argv[2]
out = {}
repo_dir = tempfile.mkdtemp(prefix="jampacked-repo-")
bpy.ops.preferences.extension_repo_add(name="Jampacked Test", remote_url="",
                                       use_custom_directory=True, custom_directory=repo_dir,
                                       type='LOCAL')
repo = next(r for r in bpy.context.preferences.extensions.repos if r.name == "Jampacked Test")
out["install"] = sorted(bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo=repo.module, enable_on_install=True))
module = f"bl_ext.{repo.module}.jampacked"
out["enabled"] = module in bpy.context.preferences.addons.keys()
out["scene_settings"] = hasattr(bpy.types.Scene, "jampacked")
out["operators"] = sorted(n for n in dir(bpy.ops.jampacked))
try:
    if mode == "full":
        import jampacked.core.api, numba, scipy, manifold3d
        out["engine_from"] = [os.path.dirname(m.__file__) for m in (numba, scipy, manifold3d)]
        out["engine_from"] += list(jampacked.__path__)
        out["site"] = bpy.utils.user_resource('EXTENSIONS', path=".local")
        bpy.ops.mesh.primitive_cube_add(size=16)
        box = bpy.context.active_object
        bpy.ops.mesh.primitive_ico_sphere_add(radius=3.0, subdivisions=1, location=(40, 0, 0))
        ball = bpy.context.active_object
        s = bpy.context.scene.jampacked
        s.container = box
        s.types.add().object = ball
        s.fidelity, s.time_budget = 'LOW', 120.0
        out["pack"] = sorted(bpy.ops.jampacked.pack())
        out["objects"] = len(s.result.objects)
        s.filepath = os.path.join(repo_dir, "out.stl")
        s.export_mode, s.shell, s.opening = 'UNION', 1.0, 'PLANE'
        out["export"] = sorted(bpy.ops.jampacked.export())
        from jampacked.export.validate import validate_file
        out["valid"] = validate_file(os.path.join(repo_dir, "out.stl")).passed
finally:
    bpy.ops.preferences.addon_disable(module=module)  # Blender hangs at exit otherwise
    out["disabled"] = not hasattr(bpy.types.Scene, "jampacked")
print("RESULT " + json.dumps(out))
'''


def _install(python: str, zip_path: Path, mode: str, tmp_path: Path, timeout: float) -> dict:
    script = tmp_path / "install.py"
    script.write_text(SCRIPT, encoding="utf-8")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "blender-user"))
    done = subprocess.run([python, str(script), str(zip_path), mode], env=env,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                          timeout=timeout)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, done.stdout[-3000:]
    return json.loads(lines[-1][len("RESULT "):])


def test_addon_zip_installs_and_enables(tmp_path):
    (zip_path,) = build.build(list(build.PLATFORMS), wheels=False, output_dir=tmp_path,
                              blender_check=True)  # Blender's own validator passes it too
    result = _install(sys.executable, zip_path, "addon", tmp_path, timeout=120)
    assert result["install"] == ["FINISHED"]
    assert result["enabled"] and result["scene_settings"] and result["disabled"]
    assert {"pack", "export", "validate", "cancel"} <= set(result["operators"])


@pytest.mark.wheels
def test_zip_with_wheels_runs_in_a_bare_blender(tmp_path):
    python = os.environ.get("JAMPACKED_BARE_BLENDER_PYTHON")
    assert python, ("set JAMPACKED_BARE_BLENDER_PYTHON to a Python with only bpy and numpy<2 "
                    "to test the zip with its wheels (about 100 MB, a minute)")
    # builds the jampacked wheel from this checkout; downloads only wheels not in addon/wheels
    (zip_path,) = build.build(["linux-x64"], output_dir=tmp_path)
    result = _install(python, zip_path, "full", tmp_path, timeout=900)
    assert result["enabled"] and result["disabled"]
    assert all(path.startswith(result["site"]) for path in result["engine_from"]), result
    assert result["pack"] == ["FINISHED"] and result["objects"] > 0
    assert result["export"] == ["FINISHED"] and result["valid"]
