"""bench/scenes.py's run process: it ends when the process that started it dies (a Dask
worker killed midway used to leave its run going beside the re-run)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import psutil
from testdata import MESHES, REPO


def test_a_run_ends_when_the_process_that_started_it_is_killed(tmp_path):
    job = {"container": "box:30x30x30", "types": ["polyhedra/convex5/polytope1.obj"],
           "seed": 1, "kwargs": {"fidelity": "low", "time_budget": 120.0}, "params": None,
           "meshes": str(MESHES)}
    # the parent starts the run as run_in_child does (its own pid in the job), then waits
    parent = textwrap.dedent(f"""
        import json, os, subprocess, sys, time
        job = dict(json.loads({json.dumps(json.dumps(job))}), parent=os.getpid())
        child = subprocess.Popen([sys.executable, {str(REPO / "bench" / "scenes.py")!r},
                                  json.dumps(job), {str(tmp_path / "out.json")!r}])
        print(child.pid, flush=True)
        time.sleep(600)
        """)
    proc = subprocess.Popen([sys.executable, "-c", parent], stdout=subprocess.PIPE, text=True)
    try:
        child = psutil.Process(int(proc.stdout.readline()))
        time.sleep(1.0)  # the run is under way (importing or packing)
        assert child.is_running() and child.status() != psutil.STATUS_ZOMBIE
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and child.is_running() \
                and child.status() != psutil.STATUS_ZOMBIE:
            time.sleep(0.1)
        gone = not child.is_running() or child.status() == psutil.STATUS_ZOMBIE
        if not gone:
            child.kill()
        assert gone, "the run went on after the process that started it was killed"
    finally:
        proc.kill()
    assert not (tmp_path / "out.json").exists() or \
        (tmp_path / "out.json").read_text() == ""
