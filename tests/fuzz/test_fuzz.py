"""A small seeded run of the input-fuzzing harness (bench/fuzz_inputs.py): generated meshes,
packing files, API and CLI arguments must end in a clear project error or a checked valid
result, never in a traceback, a hang, an invalid result or lost data (classes c-f).

The longer run: ``make fuzz SEED=3`` (1000 cases)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from testdata import REPO

HARNESS = REPO / "bench" / "fuzz_inputs.py"
BAD = "cdef"  # traceback, hang, invalid result accepted, data loss


def test_a_small_seeded_fuzz_run_finds_no_bug(tmp_path, pytestconfig):
    out = tmp_path / "report.json"
    env = dict(os.environ)
    # numba's compiled kernels survive between runs (the harness's default is a fresh
    # folder under --root, which would compile them anew every time)
    cache = getattr(pytestconfig, "cache", None)  # None under -p no:cacheprovider
    env.setdefault("NUMBA_CACHE_DIR", str(cache.mkdir("fuzz-numba") if cache is not None
                                          else tmp_path / "numba"))
    run = subprocess.run(
        [sys.executable, str(HARNESS), "--n", "40", "--seed", "7", "--root", str(tmp_path),
         "--out", str(out), "--huge-every", "0", "--mem-gb", "8"],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert out.is_file(), f"no report\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"
    report = json.loads(out.read_text())
    assert report["cases_run"] == 40 and not report["partial"]
    bad = [c for c in report["cases"] if c["cls"] in BAD]
    assert not bad, "\n\n".join(
        f"case {c['id']} ({c['kind']}, {c['gen']}): class {c['cls']} {c['exc_type']}: "
        f"{c['msg']}\n  {c.get('desc')}\n{c.get('tb') or ''}" for c in bad)
    assert report["summary"]["h"] == 0, "the harness's own generators failed"
    # the run exercised both outcomes a user meets: refusals and accepted inputs
    assert report["summary"]["a"] > 0 and report["summary"]["b"] > 0
