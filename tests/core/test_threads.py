"""The thread tuner (core/threads.py) on simulated machines; the solver's use of it is
tested in test_kernels.py."""

from __future__ import annotations

from dataclasses import asdict

import pytest

from jampacked.core.threads import ThreadTuner


def _run(tuner: ThreadTuner, rate, seconds: float, call: float = 0.01) -> None:
    """Feed the tuner solver calls of `call` seconds for `seconds` of simulated time, doing
    rate(threads, t) contact tests per second."""
    t = 0.0
    while t < seconds:
        tuner.record(rate(tuner.threads, t) * call, call)
        t += call


def test_an_idle_machine_keeps_every_thread_and_probes_less_and_less():
    tuner = ThreadTuner(2)
    _run(tuner, lambda n, t: 1400.0 if n == 2 else 1000.0, 120.0)
    assert tuner.threads == 2 and tuner.switches == 0
    # probes 0.5, 1, 2, ... 20 s apart: ten in two minutes, 0.15 s each
    assert 6 <= tuner.probes <= 12
    assert tuner.seconds[1] < 0.03 * tuner.seconds[2]


def test_a_busy_machine_moves_to_one_thread_after_the_first_probe():
    tuner = ThreadTuner(2)
    _run(tuner, lambda n, t: 30.0 if n == 2 else 1000.0, 60.0)
    assert tuner.threads == 1 and tuner.switches == 1
    # the start, the probes back to two threads: a small share of the time
    assert tuner.seconds[2] < 0.05 * 60.0
    assert tuner.report().seconds_by_threads["1"] > 55.0


def test_load_arriving_mid_run_is_noticed_within_a_probe():
    tuner = ThreadTuner(2)
    _run(tuner, lambda n, t: 1400.0 if n == 2 or t < 40.0 else 1000.0, 40.0)
    assert tuner.threads == 2 and tuner.probes >= 5  # settled: probes 20 s apart
    on_two = tuner.seconds[2]
    _run(tuner, lambda n, t: 50.0 if n == 2 else 1000.0, 20.0)
    assert tuner.threads == 1
    # the rate drop started a probe at once instead of after 20 s, and the next probe back
    # to two threads waits 20 s
    assert tuner.seconds[2] - on_two < 0.75


def test_load_going_away_brings_the_threads_back():
    tuner = ThreadTuner(2)
    _run(tuner, lambda n, t: 50.0 if n == 2 else 1000.0, 30.0)
    assert tuner.threads == 1
    _run(tuner, lambda n, t: 1400.0 if n == 2 else 1000.0, 40.0)
    assert tuner.threads == 2 and tuner.switches == 2


def test_small_differences_do_not_switch():
    tuner = ThreadTuner(2)
    _run(tuner, lambda n, t: 1000.0 if n == 2 else 1050.0, 60.0)  # within the 1.1 gain
    assert tuner.threads == 2 and tuner.switches == 0


def test_one_thread_is_never_probed():
    tuner = ThreadTuner(1)
    _run(tuner, lambda n, t: 1000.0, 10.0)
    assert tuner.threads == 1 and tuner.probes == 0
    assert asdict(tuner.report()) == {"most": 1, "switches": 0, "probes": 0,
                               "seconds_by_threads": {"1": pytest.approx(10.0, abs=0.02)}}

