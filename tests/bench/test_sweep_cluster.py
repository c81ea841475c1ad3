"""bench/run.py's scene sweep and bench/fidelity_sweep.py's runs on a real Dask LocalCluster
(two worker processes): the same records as one after another, apart from times and where
each ran, also with a worker killed midway; without a cluster nothing of Dask is started."""

from __future__ import annotations

import json
import os
import threading

import distributed
from dask_workers import kill_a_busy_worker, task_starts, transitions
from testdata import MESHES, bench_module, warm_cache_env

#: a tiny scene (about six objects, seconds per run), no bars: warm runs only
TINY = {"container": "box:22x20x21",
        "types": [f"polyhedra/convex5/polytope{i}.obj" for i in (1, 3)],
        "kwargs": {"fidelity": "low"}, "reference": "test"}
#: what differs from run to run or machine to machine
VARYING = {"wall_seconds", "cpu_seconds", "timings", "seconds", "density_trace",
           "peak_rss_mb", "threads", "cluster", "median_seconds", "median_phase_seconds",
           "phase_seconds"}
#: an attempt's times (seconds) per phase
ATTEMPT_TIMES = {"phase1", "phase2", "extra"}


def _run(monkeypatch, tmp_path):
    run = bench_module("run", siblings=True)
    monkeypatch.setitem(run.SCENES, "tiny", TINY)
    monkeypatch.setattr(run, "RESULTS", tmp_path)
    # the warm runs' numba cache: this test session's (already compiled), not a fresh one
    monkeypatch.setattr(run, "fresh_cache_env", warm_cache_env)
    return run


def _differences(a, b, path: str = "") -> list[str]:
    """The paths where two JSON values differ, keys in VARYING left out."""
    if isinstance(a, dict) and isinstance(b, dict):
        keys = (a.keys() | b.keys()) - VARYING
        if "/attempts/" in path:
            keys -= ATTEMPT_TIMES
        return [d for k in sorted(keys) for d in _differences(a.get(k), b.get(k),
                                                                f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True))
                for d in _differences(x, y, f"{path}/{i}")]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def _no_cluster(*args, **kwargs):
    raise AssertionError("a Dask cluster or client was started")


def test_the_scene_sweep_on_a_cluster_writes_the_records_of_one_after_another(
        monkeypatch, tmp_path):
    here_dir, there_dir = tmp_path / "here", tmp_path / "there"
    with monkeypatch.context() as m:
        run = _run(m, here_dir)
        m.setattr(distributed, "LocalCluster", _no_cluster)
        m.setattr(distributed, "Client", _no_cluster)
        run.run_scenes(["tiny"], [1, 2], True, MESHES)
        here = json.loads((here_dir / "tiny.json").read_text())
    assert [r["cluster"] for r in here["runs"]] == [None, None]

    run = _run(monkeypatch, there_dir)
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        runs = run.Runs(client)
        since = transitions(client)
        sweep = threading.Thread(target=run.run_scenes,
                                 args=(["tiny"], [1, 2], True, MESHES, runs))
        sweep.start()
        killed = kill_a_busy_worker(client)  # its run is run again elsewhere
        sweep.join(timeout=300)
        assert killed is not None and not sweep.is_alive()
        workers = set(client.nthreads())
        starts = task_starts(client, "bench-run-", since)
    assert len(starts) == 2 and max(starts.values()) >= 2  # the dead worker's run, again
    assert killed not in workers
    there = json.loads((there_dir / "tiny.json").read_text())
    assert _differences(there, here) == []
    assert [r["seed"] for r in there["runs"]] == [1, 2]  # each once, in order
    for r in there["runs"]:
        assert r["cluster"]["scheduler"] == cluster.scheduler_address
        assert (r["cluster"]["workers"], r["cluster"]["threads"]) == (2, 2)
        assert r["cluster"]["worker"] != killed
    assert here["runs"][0]["metrics"]["count"] > 0



def test_the_fidelity_sweep_on_a_cluster_makes_the_rows_of_one_after_another(monkeypatch):
    fid = bench_module("fidelity_sweep", siblings=True)
    monkeypatch.setitem(fid.SCENES, "tiny", TINY)
    env = dict(os.environ)
    with monkeypatch.context() as m:
        m.setattr(distributed, "LocalCluster", _no_cluster)
        m.setattr(distributed, "Client", _no_cluster)
        here = fid.sweep("tiny", [1], env, MESHES, ["low", "medium"])
    with distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        client.wait_for_workers(2, timeout=120)
        there = fid.sweep("tiny", [1], env, MESHES, ["low", "medium"], fid.Runs(client))
    assert [r["config"] for r in there] == ["low", "medium"]
    assert _differences(there, here) == []
    assert {r["cluster"]["scheduler"] for row in there for r in row["runs"]} == \
        {cluster.scheduler_address}
