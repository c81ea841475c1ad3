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


def test_a_small_seeded_fuzz_run_finds_no_bug(tmp_path):
    out = tmp_path / "report.json"
    env = dict(os.environ)
    # the harness's worker loads the kernels the rest of the suite compiled, from the same
    # numba cache (the harness's default, a fresh folder under --root, compiles them all
    # anew: a minute of the suite). An empty NUMBA_CACHE_DIR is numba's default location
    # (__pycache__ beside the package), which the harness's setdefault leaves as it is.
    env.setdefault("NUMBA_CACHE_DIR", "")
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
