"""Several output files of one export: all of them or none, every path checked before any
work, and true messages when something stops the export half-way."""

from __future__ import annotations

import dataclasses
import os
import signal
from pathlib import Path

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.core.errors import Cancelled, InputError, MeshError
from jampacked.core.meshes import load_mesh
from jampacked.core.packing import Packing, TypeRecord
from jampacked.core.packing_json import save_packing
from jampacked.core.report import PackInputs
from jampacked.export import assemble
from jampacked.export.assemble import export_packing
from jampacked.export.io import write_mesh
from jampacked.export.options import ExportOptions
from jampacked.export.validate import validate_file

P1 = mesh_path("polyhedra/convex5/polytope1.obj")
OLD = b"old"


def _cubes(tmp: Path, offset: float = 0.0, gap: float = 2e-4) -> Path:
    """Two 4-unit cubes ``gap`` apart in a 40-unit box container, everything moved by
    ``offset`` on every axis: the container is a mesh file, so the scene's coordinates are
    ``offset`` large. Returns the packing file."""
    cube = tmp / "cube.obj"
    trimesh.creation.box(extents=(4.0, 4.0, 4.0)).export(cube)
    box = trimesh.creation.box(extents=(40.0, 40.0, 40.0))
    box.apply_translation([offset] * 3)
    container = tmp / "container.stl"
    box.export(container)
    m, c = load_mesh(cube), load_mesh(container)
    rec = TypeRecord(name="cube", path=str(cube), sha256=m.sha256, share=1.0,
                     local_from_file=np.eye(4), volume=m.volume)
    pos = np.array([[offset - 2 - gap / 2, offset, offset],
                    [offset + 2 + gap / 2, offset + 1, offset + 1]])
    p = Packing(container_path=str(container), container_sha256=c.sha256,
                frame_from_file=np.eye(4), container_volume=c.volume, types=[rec],
                type_index=np.zeros(2, int), rotations=np.tile([1.0, 0, 0, 0], (2, 1)),
                translations=pos, scales=np.ones(2), inputs=PackInputs(clearance=0.0))
    out = tmp / "cubes.json"
    save_packing(p, out)
    return out


def _old_outputs(tmp: Path, *names: str) -> list[Path]:
    """Output files holding b"old", as a previous export would have left them."""
    paths = [tmp / n for n in names]
    for p in paths:
        p.write_bytes(OLD)
    return paths


def _temporaries(tmp: Path) -> list[str]:
    """Hidden files left in ``tmp``: temporaries (.NAME.XXXX.tmp.EXT) and backups (.old)."""
    return [f for f in os.listdir(tmp) if f.startswith(".")]


UNION = ExportOptions(mode="union")


# --------------------------------------------------------------------------- interrupts


def test_cancel_after_the_first_file_leaves_every_previous_file(tmp_path):
    """Issue: Ctrl-C during ``-o a.3mf -o a.stl`` replaced a.3mf, kept the old a.stl and
    said "no file was written". A cancel that comes once the first file is done now leaves
    both previous files as they were, no temporaries, and the message is true."""
    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")

    def cancel() -> bool:  # true once anything of the first file is on disk
        return a3.read_bytes() != OLD or any(".a.3mf." in f for f in os.listdir(tmp_path))

    with pytest.raises(Cancelled, match="no file was written"):
        export_packing(src, [a3, astl], UNION, should_cancel=cancel)
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []


def _on_second_validation(monkeypatch, action) -> None:
    """Run ``action()`` as the export validates its second file."""
    from jampacked.export import io

    calls = []

    def validate(path, **kw):
        calls.append(path)
        if len(calls) == 2:
            action()
        return validate_file(path, **kw)

    monkeypatch.setattr(io, "validate_file", validate)


def test_a_second_interrupt_while_validating_leaves_no_file_and_no_temporary(tmp_path,
                                                                            monkeypatch):
    """A second Ctrl-C (KeyboardInterrupt) while the second file is validated: the first
    file is not in place either."""
    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")

    def interrupt() -> None:
        raise KeyboardInterrupt

    _on_second_validation(monkeypatch, interrupt)
    with pytest.raises(KeyboardInterrupt):
        export_packing(src, [a3, astl], UNION)
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []


@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_cli_terminated_while_writing_leaves_no_temporary(signame, tmp_path, monkeypatch,
                                                          capsys):
    """SIGTERM (kill, a process manager) or SIGHUP (a closed terminal) while the second
    file is validated: they ended the process on the spot and left the first file's staged
    temporary; now the previous files stay, nothing hidden is left, the status is 128 + the
    signal's number."""
    import signal

    from jampacked.cli.main import main

    signum = getattr(signal, signame)
    before = signal.getsignal(signum)
    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    _on_second_validation(monkeypatch, lambda: signal.raise_signal(signum))
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o", str(astl), "-q"])
    assert rc == 128 + signum and "terminated" in capsys.readouterr().err
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []
    assert signal.getsignal(signum) is before  # restored


# --------------------------------------------------------------------------- all or nothing


def test_a_later_output_that_fails_validation_leaves_the_earlier_unwritten(tmp_path,
                                                                          monkeypatch):
    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    from jampacked.export import io

    def fails_stl(path, **kw):
        report = validate_file(path, **kw)
        if str(path).endswith(".stl"):
            return dataclasses.replace(report, problems=("made to fail by the test",))
        return report

    monkeypatch.setattr(io, "validate_file", fails_stl)
    with pytest.raises(MeshError, match="a.stl") as info:
        export_packing(src, [a3, astl], UNION)
    assert "no file was written" in str(info.value) and "32-bit" not in str(info.value)
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []


def _no_build(monkeypatch) -> None:
    """Fail the test if the export starts loading meshes."""
    def boom(*a, **k):
        raise AssertionError("the export started building before refusing an output")

    monkeypatch.setattr(assemble, "load_sources", boom)


@pytest.mark.parametrize("order", ["first", "last"])
def test_an_output_over_an_input_mesh_is_refused_before_any_work(tmp_path, monkeypatch,
                                                                 order):
    src = _cubes(tmp_path)
    cube = tmp_path / "cube.obj"
    before = cube.read_bytes()
    ok = tmp_path / "ok.3mf"
    outs = [ok, cube] if order == "last" else [cube, ok]
    _no_build(monkeypatch)
    with pytest.raises(InputError, match=r"cube\.obj.*input file"):
        export_packing(src, outs, UNION)
    assert not ok.exists() and cube.read_bytes() == before


def test_outputs_are_all_checked_before_any_work(tmp_path, monkeypatch):
    src = _cubes(tmp_path)
    ok = tmp_path / "ok.3mf"
    _no_build(monkeypatch)
    with pytest.raises(InputError, match="input file"):
        export_packing(src, [ok, tmp_path / "container.stl"], UNION)
    with pytest.raises(MeshError, match="does not exist"):
        export_packing(src, [ok, tmp_path / "missing" / "x.stl"], UNION)
    with pytest.raises(MeshError, match=r"cube\.obj' is a file, not a folder"):
        export_packing(src, [ok, tmp_path / "cube.obj" / "x.stl"], UNION)
    (tmp_path / "dir.stl").mkdir()
    with pytest.raises(MeshError, match="is a folder"):
        export_packing(src, [ok, tmp_path / "dir.stl"], UNION)
    with pytest.raises(InputError, match="twice"):
        export_packing(src, [ok, tmp_path / "." / "ok.3mf"], UNION)
    assert not ok.exists()


def test_a_folder_that_takes_no_file_is_refused_before_any_work(tmp_path, monkeypatch,
                                                                read_only_folder):
    # a read-only disk or an immutable folder was found only when the first file was
    # written, after the build
    src = _cubes(tmp_path)
    ro = read_only_folder
    _no_build(monkeypatch)
    ok = tmp_path / "ok.3mf"
    with pytest.raises(MeshError, match=r"ro.*takes no new file \(Read-only file system\)"):
        export_packing(src, [ok, ro / "x.stl"], UNION)
    assert not ok.exists() and not list(ro.iterdir())


def test_the_packing_file_itself_is_never_an_output(tmp_path, monkeypatch):
    src = _cubes(tmp_path)
    renamed = tmp_path / "cubes.stl"  # a packing file named like a mesh
    src.rename(renamed)
    before = renamed.read_bytes()
    _no_build(monkeypatch)
    with pytest.raises(InputError, match="input file"):
        export_packing(renamed, [tmp_path / "ok.3mf", renamed], UNION)
    assert renamed.read_bytes() == before and not (tmp_path / "ok.3mf").exists()


def test_a_rename_that_fails_midway_puts_the_files_replaced_back(tmp_path, monkeypatch):
    # an immutable second target (or a full disk) left the first one replaced: "a failure
    # changes nothing" held only for the files not yet renamed
    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    fresh = tmp_path / "fresh.obj"  # a new file among them is removed again
    real = os.replace

    def stl_fails(a, b):
        if os.fspath(b) == os.fspath(astl):
            raise OSError(1, "Operation not permitted")
        real(a, b)

    monkeypatch.setattr(os, "replace", stl_fails)
    with pytest.raises(MeshError) as info:
        export_packing(src, [a3, fresh, astl], UNION)
    text = str(info.value)
    assert "a.stl" in text and "Operation not permitted" in text
    assert "No file was written; every output file is as it was" in text
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD and not fresh.exists()
    assert _temporaries(tmp_path) == []
    # a backup that cannot be put back is kept, and named: the previous contents live on
    def stl_and_restore_fail(a, b):
        if os.fspath(b) == os.fspath(astl) or os.fspath(a).endswith(".old"):
            raise OSError(1, "Operation not permitted")
        real(a, b)

    monkeypatch.setattr(os, "replace", stl_and_restore_fail)
    with pytest.raises(MeshError) as info:
        export_packing(src, [a3, astl], UNION)
    (backup,) = _temporaries(tmp_path)
    assert f"the previous contents of '{a3}' are in '{tmp_path / backup}'" in str(info.value)
    assert (tmp_path / backup).read_bytes() == OLD and astl.read_bytes() == OLD
    os.unlink(tmp_path / backup)
    a3.write_bytes(OLD)
    monkeypatch.setattr(os, "replace", stl_fails)
    # where the file system has no hard links, what was replaced is named instead
    monkeypatch.setattr(os, "link", lambda *a: (_ for _ in ()).throw(OSError(1, "no links")))
    with pytest.raises(MeshError) as info:
        export_packing(src, [a3, astl], UNION)
    text = str(info.value)
    assert "'" + str(a3) + "' was replaced" in text and "kept its previous" in text
    assert a3.read_bytes() != OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []


def test_cli_multi_output_all_or_nothing(tmp_path, capsys):
    from jampacked.cli.main import main

    src = _cubes(tmp_path)
    a3, astl = tmp_path / "a.3mf", tmp_path / "a.stl"
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o",
               str(tmp_path / "cube.obj")])
    err = capsys.readouterr().err
    assert rc in (1, 2) and "cube.obj" in err and not a3.exists()
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o", str(astl), "-q"])
    assert rc == 0 and validate_file(a3).passed and validate_file(astl).passed


# --------------------------------------------------------------------------- float32 files


def test_float32_rounding_far_from_the_origin_is_named_and_nothing_written(tmp_path,
                                                                          monkeypatch):
    """Issue: a scene 1e4 units from the origin exported to 3MF and STL left the 3MF
    written and refused the STL as "not watertight ... a defect: report it". STL stores
    32-bit floats: at 1e4 their step is about 1e-3, which closes the 2e-4 gap between the
    cubes. The export now says so, before writing anything."""
    from jampacked.export import io

    src = _cubes(tmp_path, offset=1e4)
    a3, astl = tmp_path / "far.3mf", tmp_path / "far.stl"
    with monkeypatch.context() as m:
        def no_write(*a, **k):
            raise AssertionError("a file was written before the float32 check")

        m.setattr(io, "stage_mesh_file", no_write)
        with pytest.raises(MeshError) as info:
            export_packing(src, [a3, astl], UNION)
    text = str(info.value)
    assert "far.stl" in text and "32-bit" in text and "1e+04" in text
    assert "3MF" in text and "origin" in text and "report" not in text
    assert not a3.exists() and not astl.exists() and _temporaries(tmp_path) == []
    # the same scene as 3MF alone, and near the origin as STL, pass
    assert export_packing(src, a3, UNION).passed
    near = tmp_path / "near"
    near.mkdir()
    assert export_packing(_cubes(near), near / "near.stl", UNION).passed


def test_write_mesh_names_float32_rounding_as_the_cause(tmp_path):
    """The writer's own message, for any caller: a mesh that is watertight in float64 but
    not once rounded to float32 (STL, PLY) is refused naming the format's precision."""
    a = trimesh.creation.box(bounds=[[0, 0, 0], [1, 1, 1]])
    b = trimesh.creation.box(bounds=[[1 + 2e-4, 0, 0], [2, 1, 1]])
    bodies = [(np.asarray(m.vertices) + 1e4, np.asarray(m.faces)) for m in (a, b)]
    assert write_mesh(tmp_path / "ok.3mf", bodies).passed
    for ext, name in (("stl", "STL"), ("ply", "PLY")):
        with pytest.raises(MeshError) as info:
            write_mesh(tmp_path / f"x.{ext}", bodies)
        text = str(info.value)
        assert f"{name} stores" in text and "32-bit" in text and "1e+04" in text
        assert "report" not in text and not (tmp_path / f"x.{ext}").exists()


# --------------------------------------------------------------------------- Ctrl-C at the end


@pytest.fixture
def python_ctrl_c():
    """Python's own Ctrl-C handler (KeyboardInterrupt) for the test, whatever an earlier
    test in this process left: a test process of `make test` runs many files, and Blender
    (the add-on tests' bpy) leaves SIGINT ignored, so the test below passed or failed by
    the files' order (as `test_cli.py`'s Ctrl-C tests already allow for)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def _ctrl_c_on_first_rename(monkeypatch, signum: int = signal.SIGINT) -> list[str]:
    """A Ctrl-C (SIGINT to this process; or ``signum``) just as the first file is renamed
    into place. Returns the list that records the rename it was sent at."""
    real = os.replace
    sent: list[str] = []

    def replace(a, b):
        if not sent:
            sent.append(b)
            os.kill(os.getpid(), signum)
        real(a, b)

    monkeypatch.setattr(os, "replace", replace)
    return sent


def test_ctrl_c_while_files_are_put_in_place_waits_until_all_are(tmp_path, monkeypatch,
                                                                  python_ctrl_c):
    """A KeyboardInterrupt between two renames would leave a mixed pair: it is held back
    until every file is in place, then raised naming them."""
    from jampacked.export.io import MeshOutput, write_meshes

    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    box = trimesh.creation.box()
    _ctrl_c_on_first_rename(monkeypatch)
    with pytest.raises(KeyboardInterrupt) as info:
        write_meshes([MeshOutput(a3, box.vertices, box.faces),
                      MeshOutput(astl, box.vertices, box.faces)])
    assert info.value.replaced == [str(a3), str(astl)]
    assert a3.read_bytes() != OLD and astl.read_bytes() != OLD
    assert _temporaries(tmp_path) == []


def test_cli_ctrl_c_after_validation_says_the_files_were_written(tmp_path, monkeypatch,
                                                                 capsys):
    from jampacked.cli.main import main

    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    _ctrl_c_on_first_rename(monkeypatch)
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o", str(astl), "-q"])
    err = " ".join(capsys.readouterr().err.split())
    assert rc == 0 and "export was completed and its files written" in err
    assert validate_file(a3).passed and validate_file(astl).passed


def test_cli_sigterm_while_files_are_put_in_place_waits_until_all_are(tmp_path, monkeypatch):
    """SIGTERM between two renames left the first file new, the second old and a backup
    beside it: it is held back as a Ctrl-C is, until every file is in place."""
    from jampacked.cli.main import main

    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")
    sent = _ctrl_c_on_first_rename(monkeypatch, signal.SIGTERM)
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o", str(astl), "-q"])
    assert sent and rc == 128 + signal.SIGTERM
    assert validate_file(a3).passed and validate_file(astl).passed
    assert _temporaries(tmp_path) == []


def test_cli_terminated_inside_a_compiled_kernel_is_still_terminated(tmp_path, monkeypatch,
                                                                     capsys):
    """A SIGTERM while a numba kernel calls back into Python comes out as a SystemError
    ("returned a result with an exception set") around the Terminated: it was a traceback
    and exit status 1."""
    from jampacked.cli.interrupt import Terminated
    from jampacked.cli.main import main
    from jampacked.export import io

    src = _cubes(tmp_path)
    a3, astl = _old_outputs(tmp_path, "a.3mf", "a.stl")

    def kernel_interrupted(path, **kw):
        try:
            raise Terminated(signal.SIGTERM)
        except Terminated:
            raise SystemError("CPUDispatcher(<function band_distances>) returned a result "
                              "with an exception set") from None

    monkeypatch.setattr(io, "validate_file", kernel_interrupted)
    rc = main(["export", str(src), "--mode", "union", "-o", str(a3), "-o", str(astl), "-q"])
    err = capsys.readouterr().err
    assert rc == 128 + signal.SIGTERM and "terminated" in err and "Traceback" not in err
    assert a3.read_bytes() == OLD and astl.read_bytes() == OLD
    assert _temporaries(tmp_path) == []


def test_a_signal_the_process_ignores_stays_ignored():
    """nohup ignores SIGHUP so that a run outlives its terminal: the command line's handler
    for SIGTERM and SIGHUP is not installed over an ignored signal."""
    from jampacked.cli.interrupt import TerminateCleanly

    before = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with TerminateCleanly():
            assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) == TerminateCleanly._handler
            signal.raise_signal(signal.SIGHUP)  # ignored: nothing happens
        assert signal.getsignal(signal.SIGHUP) == signal.SIG_IGN
    finally:
        signal.signal(signal.SIGHUP, before)


def test_outputs_differing_only_in_case_are_one_file_on_macos(tmp_path, monkeypatch):
    """On macOS (a case-insensitive volume as a rule) a.stl and a.STL are one file: two
    temporaries were renamed onto it and both reported written."""
    from jampacked.export import io as export_io

    monkeypatch.setattr(export_io.sys, "platform", "darwin")
    with pytest.raises(InputError, match="named twice"):
        export_io.check_output_paths([str(tmp_path / "a.stl"), str(tmp_path / "a.STL")])
    monkeypatch.setattr(export_io.sys, "platform", "linux")
    export_io.check_output_paths([str(tmp_path / "a.stl"), str(tmp_path / "a.STL")])
