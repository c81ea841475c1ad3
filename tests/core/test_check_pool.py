"""Tests for jampacked.core.check_pool: a certification's exact checks in worker processes
give the report the certifier's own process gives, fall back to it when the workers fail,
and leave no process behind."""

from __future__ import annotations

import logging
import multiprocessing
import os
import signal
from concurrent.futures.process import BrokenProcessPool
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from testdata import mesh_path

from jampacked.core import certify, check_pool
from jampacked.core.api import pack
from jampacked.core.certify import Certifier, CheckMemo
from jampacked.core.container import build_container
from jampacked.core.options import CavityPassOptions, FidelityOverrides, PackOptions
from jampacked.core.rotations import quat_to_matrix


def _certifier(processes: int) -> Certifier:
    box = trimesh.creation.box(extents=(30.0, 30.0, 30.0))
    cont = build_container(box.vertices, box.faces, float(box.volume), 1.0)
    meshes = [trimesh.creation.box(extents=(2.0, 3.0, 4.0)),
              trimesh.creation.icosphere(subdivisions=2, radius=1.5)]
    return Certifier(cont, [np.asarray(m.vertices) for m in meshes],
                     [np.asarray(m.faces) for m in meshes],
                     np.array([m.volume for m in meshes]),
                     np.array([m.edges_unique_length.max() for m in meshes]),
                     processes=processes)


def _scene(n=120, seed=4):
    """Objects close enough that many pairs touch or overlap and some poke through the
    wall, and one wholly outside."""
    rng = np.random.default_rng(seed)
    typ = rng.integers(0, 2, n)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    m = np.tile(np.eye(4), (n, 1, 1))
    m[:, :3, :3] = quat_to_matrix(q)
    m[:, :3, 3] = rng.uniform(-15.5, 15.5, (n, 3)) * [1.0, 1.0, 0.5]
    m[-1, :3, 3] = [300.0, 0.0, 0.0]
    return typ, m


def _same(a, b):
    assert a.as_dict() == b.as_dict()
    assert a.bad_pairs == b.bad_pairs and a.bad_wall == b.bad_wall
    assert a.pair_shortfall == b.pair_shortfall and a.wall_shortfall == b.wall_shortfall


@pytest.fixture
def eager_pool(monkeypatch):
    """Worker processes from the first checks on, in small chunks."""
    monkeypatch.setattr(certify, "POOL_PROBE_SECONDS", 0.0)
    monkeypatch.setattr(certify, "POOL_MIN_SECONDS", 0.0)
    monkeypatch.setattr(check_pool, "CHUNK_CHECKS", 7)


@pytest.mark.parametrize("clearance", [0.0, 0.4])
def test_workers_give_the_report_of_one_process(eager_pool, clearance):
    typ, m = _scene()
    here = _certifier(1).certify(typ, m, clearance)
    assert not here.certified and here.bad_pairs and here.bad_wall
    calls = []
    memo = CheckMemo()
    with _certifier(2) as cert:
        got = cert.certify(typ, m, clearance, memo=memo,
                           progress=lambda done, total: calls.append((done, total)))
        assert cert._pool is not None  # the checks ran on the workers
        workers = list(cert._pool._pool._processes.values())
        _same(got, here)
        assert memo.run == got.pairs_checked + got.walls_checked
        # a repair's next certification: what moved is checked again, on the workers
        m2 = m.copy()
        m2[:10, :3, 3] += [0.3, -0.2, 0.1]
        _same(cert.certify(typ, m2, clearance, memo=memo),
              _certifier(1).certify(typ, m2, clearance))
    assert cert._pool is None and workers and not any(w.is_alive() for w in workers)
    total = calls[-1][1]
    assert calls[-1] == (total, total) and [d for d, _ in calls] == sorted(d for d, _ in calls)


@pytest.mark.parametrize("error", [BrokenProcessPool("a worker died"),
                                   RuntimeError("a worker died before it started")])
def test_failed_workers_leave_the_checks_to_this_process(eager_pool, monkeypatch, caplog,
                                                         error):
    def broken(*args, **kwargs):
        raise error

    monkeypatch.setattr(check_pool.CheckPool, "run", broken)
    typ, m = _scene()
    with caplog.at_level(logging.WARNING), _certifier(2) as cert:
        _same(cert.certify(typ, m, 0.4), _certifier(1).certify(typ, m, 0.4))
        assert str(error) in caplog.text and cert._pool is None
        _same(cert.certify(typ, m, 0.0), _certifier(1).certify(typ, m, 0.0))
        assert cert._pool is None  # not started again


def test_workers_outlive_a_ctrl_c(eager_pool):
    """Ctrl-C in a terminal reaches the workers too: the command line's first one only
    cancels the placement, and the certification after it must not lose its workers."""
    typ, m = _scene()
    with _certifier(2) as cert:
        first = cert.certify(typ, m)
        workers = list(cert._pool._pool._processes.values())
        for w in workers:
            os.kill(w.pid, signal.SIGINT)
        _same(cert.certify(typ, m), first)
        assert cert._pool is not None and all(w.is_alive() for w in workers)


def test_short_certifications_and_daemonic_processes_start_no_workers(monkeypatch):
    typ, m = _scene(30)
    with _certifier(2) as cert:  # the default thresholds: 30 objects take milliseconds
        cert.certify(typ, m)
        assert cert._pool is None
    assert check_pool.usable_processes(3) == 3
    assert check_pool.usable_processes(0) >= 1
    monkeypatch.setattr(check_pool.multiprocessing, "current_process",
                        lambda: SimpleNamespace(daemon=True))
    assert check_pool.usable_processes(0) == 1 and check_pool.usable_processes(4) == 1


@pytest.mark.parametrize(("executable", "python"), [
    ("/usr/bin/python3.11", True), ("C:\\Python311\\pythonw.exe", True),
    ("/opt/blender-4.2/4.2/python/bin/python3.11", True), ("/usr/bin/pypy3", True),
    (b"/usr/bin/python3", True),  # POSIX: bytes
    ("/opt/blender-2.90/blender", False), ("/Applications/Some App", False)])
def test_workers_start_only_where_spawn_runs_python(monkeypatch, executable, python):
    """An application embedding Python may give its own binary as the executable:
    spawning it would start the application again, not a worker."""
    from multiprocessing import spawn

    monkeypatch.setattr(spawn, "get_executable", lambda: executable)
    assert check_pool._spawns_python() is python
    assert (check_pool.usable_processes(3) == 3) is python


@pytest.mark.parametrize(("cpu_max", "cores"), [("150000 100000\n", 2), ("50000 100000", 1),
                                                ("max 100000", 64), ("garbled", 64),
                                                (None, 64)])
def test_a_containers_cpu_quota_bounds_the_workers(monkeypatch, tmp_path, cpu_max, cores):
    """A container limited to a few CPUs still sees every host core in its affinity: one
    worker per host core would crowd its quota."""
    path = tmp_path / "cpu.max"
    if cpu_max is not None:
        path.write_text(cpu_max)
    monkeypatch.setattr(check_pool, "CPU_MAX", path)
    monkeypatch.setattr(check_pool.os, "sched_getaffinity", lambda pid: set(range(64)),
                        raising=False)
    assert check_pool.usable_processes(0) == cores
    assert check_pool.usable_processes(3) == 3  # asked for: as asked


def test_a_packing_certified_on_workers_is_the_same(eager_pool, monkeypatch):
    runs = []
    run_here = check_pool.CheckPool.run
    monkeypatch.setattr(check_pool.CheckPool, "run",
                        lambda self, *a, **k: runs.append(1) or run_here(self, *a, **k))
    fruit = [str(mesh_path(f"fruit/ycb_lowpoly/{n}.obj")) for n in ("017_orange", "014_lemon")]
    # a coarse model leaves overlaps: the repair's rounds certify again what moved. One
    # cavity pass, not four: the repair still takes three rounds (after four passes its
    # pushes took most of 30 s)
    base = replace(PackOptions(), fidelity=FidelityOverrides(surface_points=96),
                   cavity=CavityPassOptions(factors=(0.8,)))

    def run(processes):
        opts = replace(base, repair=replace(base.repair, processes=processes))
        return pack("box:20x20x20", fruit, seed=4, type_scale=100.0, fidelity="low",
                    options=opts)

    one = run(1)
    assert not runs
    two = run(2)
    assert len(runs) >= one.report.repair.rounds > 0 and one.certificate["pairs_checked"] > 0
    assert one.certificate == two.certificate
    np.testing.assert_array_equal(one.translations, two.translations)
    assert multiprocessing.active_children() == []


def test_a_script_without_a_main_guard_runs_once(tmp_path):
    """Spawned workers import the main script again unless it is hidden from them: a
    script that certifies at its top level (no `if __name__ == "__main__":`) would run
    again in every worker, and each would try to start workers of its own."""
    import subprocess
    import sys
    from pathlib import Path

    runs = tmp_path / "runs.txt"
    script = tmp_path / "unguarded.py"
    script.write_text(f"""
import sys
sys.path[:0] = {[str(Path(__file__).parent), str(Path(__file__).parent.parent)]!r}
with open({str(runs)!r}, "a") as f:
    f.write("ran\\n")
from jampacked.core import certify, check_pool
import test_check_pool as t
certify.POOL_PROBE_SECONDS = certify.POOL_MIN_SECONDS = 0.0
check_pool.CHUNK_CHECKS = 7
typ, m = t._scene()
with t._certifier(2) as cert:
    rep = cert.certify(typ, m)
    assert cert._pool is not None and not cert._pool_broken
print(rep.pairs_checked, rep.certified)
""")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert runs.read_text() == "ran\n"
    assert done.stdout.split()[1] == "False" and int(done.stdout.split()[0]) > 0
