"""Atomic writes (`core/atomic.py`): a new file's permissions follow the user's umask, as
any program's would; a replaced file keeps its own."""

from __future__ import annotations

import os
import stat
import subprocess
import sys

import pytest

WRITE = """
import os, sys
from jampacked.core.atomic import atomic_output
with atomic_output(sys.argv[1], "w") as f:
    f.write("x")
print(oct(os.stat(sys.argv[1]).st_mode & 0o777))
"""


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permission bits")
@pytest.mark.parametrize("umask, mode", [(0o077, "0o600"), (0o002, "0o664"), (0o022, "0o644")])
def test_a_new_file_has_the_permissions_the_umask_gives(tmp_path, umask, mode):
    out = subprocess.run([sys.executable, "-c", WRITE, str(tmp_path / "new.json")],
                         capture_output=True, text=True, check=True,
                         preexec_fn=lambda: os.umask(umask))
    assert out.stdout.strip() == mode


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permission bits")
def test_a_replaced_file_keeps_its_permissions(tmp_path):
    path = tmp_path / "old.json"
    path.write_text("old")
    path.chmod(0o640)
    out = subprocess.run([sys.executable, "-c", WRITE, str(path)], capture_output=True,
                         text=True, check=True)
    assert out.stdout.strip() == "0o640" and path.read_text() == "x"
    assert stat.S_IMODE(path.stat().st_mode) == 0o640
