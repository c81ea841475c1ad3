"""bench/growth.py's budgeted method: the whole method with a time budget per size."""

from __future__ import annotations

import json

import pytest
from testdata import MESHES, bench_module, warm_cache_env

growth = bench_module("growth", siblings=True)


@pytest.mark.serial
def test_budgeted_runs_the_whole_method_with_each_sizes_budget(tmp_path, monkeypatch):
    monkeypatch.setattr(growth, "RESULTS", tmp_path)
    monkeypatch.setattr(growth, "fresh_cache_env", warm_cache_env)
    assert growth.main(["--method", "budgeted", "--counts", "12", "--budgets", "1.5",
                        "--seed", "2", "--out", "growth_seed2",
                        "--meshes", str(MESHES)]) == 0
    data = json.loads((tmp_path / "growth_seed2.json").read_text())
    (run,) = data["runs"]
    assert data["method"] == "budgeted" and run["budget"] == 1.5 and run["target"] == 12
    assert run["seed"] == 2 and run["metrics"]["count"] > 0 and run["certificate"]["certified"]
    assert "extra" in run["timings"]  # the extra passes ran: the whole method
    assert set(run["time_to_density"]) == {f"{lv:.2f}" for lv in growth.LEVELS}
    assert set(data["level_fits"]) == set(run["time_to_density"])
    assert (tmp_path / "growth_seed2.png").stat().st_size > 0


def test_budgets_must_match_the_counts(capsys):
    with pytest.raises(SystemExit):
        growth.main(["--method", "budgeted", "--counts", "10", "20", "--budgets", "5"])
    assert "2 counts" in capsys.readouterr().err


def test_time_to_density_is_the_first_report_at_the_level():
    trace = [(1.0, 0.40), (2.5, 0.571), (3.0, 0.56), (4.0, 0.585)]
    assert growth.time_to_density(trace, 0.57) == 2.5
    assert growth.time_to_density(trace, 0.58) == 4.0
    assert growth.time_to_density(trace, 0.59) is None
    assert growth.times_to_levels(trace)["0.58"] == 4.0


def test_level_fits_need_every_run_in_range_to_reach_the_level():
    def run(n, t58, t59):
        return {"metrics": {"count": n}, "time_to_density": {"0.58": t58, "0.59": t59}}

    runs = [run(500, 1.0, 1.0), run(1000, 2.0, 3.0), run(4000, 8.0, None)]
    out = growth.level_fits(runs, 1000)
    assert out["0.58"]["reached"] == 2 and out["0.58"]["runs"] == 2
    assert out["0.58"]["fit"]["exponent"] == pytest.approx(1.0)  # 2 s -> 8 s for 4x
    assert out["0.59"]["fit"] is None and out["0.59"]["reached"] == 1
