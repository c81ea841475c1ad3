"""bench/growth.py's budgeted method: the whole method with a time budget per size."""

from __future__ import annotations

import json

import pytest
from testdata import MESHES, bench_module

growth = bench_module("growth", siblings=True)


def test_budgeted_runs_the_whole_method_with_each_sizes_budget(tmp_path, monkeypatch):
    monkeypatch.setattr(growth, "RESULTS", tmp_path)
    assert growth.main(["--method", "budgeted", "--counts", "12", "--budgets", "1.5",
                        "--meshes", str(MESHES)]) == 0
    data = json.loads((tmp_path / "growth_budgeted.json").read_text())
    (run,) = data["runs"]
    assert data["method"] == "budgeted" and run["budget"] == 1.5 and run["target"] == 12
    assert run["metrics"]["count"] > 0 and run["certificate"]["certified"]
    assert "extra" in run["timings"]  # the extra passes ran: the whole method
    assert (tmp_path / "growth_budgeted.png").stat().st_size > 0


def test_budgets_must_match_the_counts(capsys):
    with pytest.raises(SystemExit):
        growth.main(["--method", "budgeted", "--counts", "10", "20", "--budgets", "5"])
    assert "2 counts" in capsys.readouterr().err
