"""How many of numba's threads the solver's contact tests use, chosen by timing them.

On an idle machine two threads test contacts 1.3-1.5 times faster than one. On cores shared
with other busy processes (a render, a second packing, Blender itself) each iteration's
parallel region waits at its barrier for a thread the OS has descheduled, and the same
placement took 4 to 18 times as long (bench/busy_machine.py). No setting of the thread layer
fits both cases, so the solver measures its own throughput: every so often it spends a short
probe on the other thread count and keeps whichever tested more contacts per second.

Thread counts never change a packing: the contact tests split into a fixed number of
chunks whatever the thread count (`kernels.CONTACT_CHUNKS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .report import ThreadReport


@dataclass
class ThreadTuner:
    """Chooses between `most` threads and one from the rate of work the solver reports.

    `record(work, seconds)` after each solver call (work: contact tests, seconds: wall time
    of the call); `threads` is the count to run the next call with. After `period` seconds
    on the chosen count it probes the other count for `probe` seconds and switches when that
    was `gain` times faster than the chosen count's latest `probe` seconds. A probe that
    confirms the choice doubles the period (up to `longest`), so that a settled machine
    pays for few probes (on a busy one a probe on every thread is the slow one); a switch
    keeps it. The chosen count's rate falling below half its previous measure (the machine
    got busier) starts a probe at once.
    """

    most: int
    probe: float = 0.15
    period: float = 0.5
    longest: float = 20.0
    gain: float = 1.1
    threads: int = field(init=False)
    switches: int = field(init=False, default=0)
    probes: int = field(init=False, default=0)
    seconds: dict[int, float] = field(init=False)

    def __post_init__(self) -> None:
        self.most = max(1, int(self.most))
        self.threads = self.most
        self._choice = self.most
        self._wait = self.period
        self._held = 0.0  # seconds on the choice since the last probe
        self._tail = [0.0, 0.0]  # work and seconds on the choice, filling up to `probe`
        self._rate: float | None = None  # the choice's rate over its latest full tail
        self._probe = [0.0, 0.0]
        self.seconds = {n: 0.0 for n in sorted({1, self.most})}

    def record(self, work: float, seconds: float) -> None:
        """Account one solver call that ran on `self.threads` threads."""
        self.seconds[self.threads] += seconds
        if self.most == 1:
            return
        if self.threads != self._choice:
            self._probe[0] += work
            self._probe[1] += seconds
            if self._probe[1] >= self.probe:
                self._decide(self._probe[0] / self._probe[1])
            return
        self._held += seconds
        self._tail[0] += work
        self._tail[1] += seconds
        if self._tail[1] >= self.probe:
            rate = self._tail[0] / self._tail[1]
            if self._rate is not None and rate < 0.5 * self._rate:
                self._held = self._wait  # slowed down: probe now
            self._rate = rate
            self._tail = [0.0, 0.0]
        if self._rate is not None and self._held >= self._wait:
            self.threads = 1 if self._choice == self.most else self.most
            self._probe = [0.0, 0.0]
            self.probes += 1

    def _decide(self, probe_rate: float) -> None:
        if probe_rate > self.gain * (self._rate or 0.0):
            self._choice = self.threads
            self.switches += 1
            self._rate = probe_rate
        else:
            self._wait = min(2.0 * self._wait, self.longest)
        self.threads = self._choice
        self._held = 0.0
        self._tail = [0.0, 0.0]

    def report(self) -> ThreadReport:
        """What the packing records: the counts used, for how long, and how often it moved."""
        return ThreadReport(most=self.most, switches=self.switches, probes=self.probes,
                            seconds_by_threads={str(n): round(s, 3)
                                                for n, s in self.seconds.items()})
