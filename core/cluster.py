"""The attempts of one packing side by side on a Dask cluster (`distributed`).

Each attempt's random stream comes from the seed and its index (`placement.attempt_rng`), so
the attempts are independent: a worker runs `run_attempt` on a fresh solver state and sends
back plain arrays and statistics (`AttemptResult`, never the numba solver); the client ranks
them by density, ties to the lowest index, exactly as `placement.place` does one after
another with the same fixed count, and certifies them as usual. Frames and units: container
frame, container units; times in seconds.

`client_for` turns what the user gave (a `distributed.Client`, a scheduler address, or a
number of local worker processes) into a client. Workers load numba's machine code from the
same on-disk cache as the client (the package's ``__pycache__`` or NUMBA_CACHE_DIR), so they
compile nothing the client has compiled.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numba
import numpy as np

from .container import Container
from .errors import InputError
from .objects import ObjectType
from .options import PackOptions
from .phases import Stop
from .placement import Attempt, attempt_rng, place_once, ranked_with
from .report import AttemptSummary, ExtraPassStats, PhaseStats
from .solver import PackState, Solver, SolverParams, TypeTable
from .threads import ThreadTuner

#: seconds between a worker's looks at the shared cancel flag (each is a round trip)
CANCEL_POLL = 0.5
#: seconds between the client's looks at the attempts' futures and its cancel callback
WAIT_POLL = 0.1
_STATE_FIELDS = ("typ", "pos", "quat", "scale", "alive", "margin", "vel")


@dataclass
class AttemptJob:
    """Everything an attempt needs besides its index: the scene as the placement sees it."""

    container: Container
    types: list[ObjectType]
    params: SolverParams
    q: np.ndarray  # (T,) target shares
    s1: float  # phase 1 lattice spacing
    f_min: float  # smallest type's equivalent radius
    seed: int
    margin: np.ndarray  # (T,) contact margins
    options: PackOptions
    c_volume: float  # container volume
    deadline: float | None = None  # wall-clock time (time.time()) placement must end by
    cancel_event: str | None = None  # name of the distributed.Event that cancels


@dataclass
class AttemptResult:
    """One attempt as a worker returns it: the solver state's arrays and the statistics."""

    index: int
    n: int
    state: dict[str, np.ndarray]  # PackState's arrays (full capacity)
    density: float
    after: dict
    phase1: PhaseStats
    phase2: PhaseStats
    extra_passes: list[ExtraPassStats]
    timings: dict
    stopped: str | None  # the attempt's stop reason ("deadline", "cancelled") or None
    worker: str = ""
    given_up: list[dict] = field(default_factory=list)  # `Attempt.given_up`

    def to_attempt(self, solver: Solver) -> Attempt:
        """The Attempt on `solver` (a fresh one), its state replaced by this result's."""
        state = solver.s
        for name in _STATE_FIELDS:
            setattr(state, name, self.state[name])
        state.n = self.n
        return Attempt(solver=solver, density=self.density, after=self.after,
                       phase1=self.phase1, phase2=self.phase2,
                       extra_passes=self.extra_passes, timings=self.timings,
                       given_up=self.given_up, index=self.index)


class _SharedCancel:
    """should_cancel() on a worker: the client's distributed.Event, looked at every
    CANCEL_POLL seconds at most."""

    def __init__(self, name: str):
        from distributed import Event

        self.event = Event(name)
        self.last = -np.inf
        self.set = False

    def __call__(self) -> bool:
        now = time.monotonic()
        if not self.set and now - self.last >= CANCEL_POLL:
            self.last = now
            self.set = bool(self.event.is_set())
        return self.set


def run_attempt(job: AttemptJob, index: int) -> AttemptResult:
    """Attempt `index` of the job's packing on a fresh state (runs on a worker)."""
    table = TypeTable(job.types)
    tuner = ThreadTuner(numba.get_num_threads()) if job.options.tune_threads else None

    def new_solver() -> Solver:
        return Solver(job.container, table, PackState(), job.params, tuner)

    solver = new_solver()
    solver.warm_up()  # numba's cache: a load, not a compile
    deadline = None
    if job.deadline is not None:
        deadline = time.perf_counter() + (job.deadline - time.time())
    stop = Stop(deadline, None if job.cancel_event is None else _SharedCancel(job.cancel_event))
    att = place_once(solver, job.q, job.s1, job.f_min, attempt_rng(job.seed, index), stop,
                     job.margin, job.options, job.c_volume, deadline is not None,
                     lambda f, m: None, index=index, fresh=new_solver)
    solver = att.solver
    s = solver.s
    try:
        from distributed import get_worker

        worker = get_worker().address
    except ValueError:  # not on a worker (called directly)
        worker = ""
    return AttemptResult(
        index=index, n=s.n, state={name: getattr(s, name) for name in _STATE_FIELDS},
        density=att.density, after=att.after, phase1=att.phase1, phase2=att.phase2,
        extra_passes=att.extra_passes, timings=att.timings, stopped=stop.reason or None,
        worker=worker, given_up=att.given_up)


def place_on_cluster(client, job: AttemptJob, count: int, new_solver: Callable[[], Solver],
                     stop: Stop, report: Callable[[float, str], None]
                     ) -> tuple[list[Attempt], list[AttemptSummary]]:
    """Attempts 0..count-1 of `job` on the client's workers; returns the densest ones as
    `placement.ranked_with` ranks them (ties: the lower index first), each rebuilt on a
    `new_solver()`, and every attempt's summary in index order.
    `stop.should_cancel()` is polled here and passed on to the workers, which stop their
    attempts and return what they have, as a local attempt does."""
    from distributed import Event

    event_name = None
    if stop.should_cancel is not None:
        event_name = f"jampacked-cancel-{uuid.uuid4().hex}"
    job.cancel_event = event_name
    event = Event(event_name, client=client) if event_name is not None else None
    if stop.deadline is not None:
        job.deadline = time.time() + (stop.deadline - time.perf_counter())
    [shared] = client.scatter([job], broadcast=True, hash=False)
    futures = [client.submit(run_attempt, shared, i, pure=False, key=f"attempt-{i}-"
                             f"{uuid.uuid4().hex[:8]}") for i in range(count)]
    try:
        finished = 0
        report(0.05, f"{count} attempts on the cluster")
        while finished < count:
            if event is not None and stop.should_cancel():
                event.set()  # the workers' attempts stop and return what they have
                stop.reason = "cancelled"
            done = sum(f.done() for f in futures)
            if done != finished:
                finished = done
                report(0.05 + 0.85 * finished / count,
                       f"{finished} of {count} attempts done")
            time.sleep(WAIT_POLL)
        results = client.gather(futures)
    finally:
        for f in futures:
            f.release()
        if event is not None:
            with contextlib.suppress(Exception):
                event.clear()
    ranked: list[AttemptResult] = []
    summaries: list[AttemptSummary] = []
    for r in sorted(results, key=lambda r: r.index):
        ranked = ranked_with(ranked, r)  # the same rule as one after another
        summaries.append(AttemptSummary(
            density=r.density, count=r.after["after_extra"]["count"],
            seconds=sum(r.timings.values()), stopped=r.stopped,
            **{k: r.timings[k] for k in ("phase1", "phase2", "extra")}))
    if not stop.reason:
        stop.reason = next((s.stopped for s in summaries if s.stopped == "deadline"), "")
    return [r.to_attempt(new_solver()) for r in ranked], summaries


def cluster_threads(client) -> int:
    """The number of worker threads the client's cluster has now (at least 1)."""
    return max(1, sum(client.nthreads().values()))


#: how long connecting to a scheduler address may take before it is reported unreachable
CONNECT_TIMEOUT = "10s"


def _check_address(target: str) -> None:
    """Refuse a TCP or TLS scheduler address without a host and a port, before a Client is
    made of it: distributed raises a bare ValueError then, and the Client it leaves half
    made stops the next one in the same process from starting."""
    from distributed.comm.addressing import get_address_host_port, parse_address

    try:
        scheme, _ = parse_address(target, strict=False)
        if scheme in ("tcp", "tls"):
            get_address_host_port(target, strict=False)
    except ValueError as exc:
        raise InputError(f"the Dask scheduler address {target!r} is not of the form "
                         f"tcp://HOST:PORT ({exc}); give the address 'dask scheduler' "
                         "prints, e.g. tcp://10.0.0.5:8786.") from None


@contextlib.contextmanager
def client_for(target=None, *, workers: int | None = None) -> Iterator:
    """A distributed.Client for what the user gave: a Client (used as is, left open), a
    scheduler address ("tcp://host:8786"; connected, closed after) or, with `workers`, a new
    LocalCluster of that many single-threaded worker processes (closed after). An address
    that is not of the form tcp://HOST:PORT, or that nothing answers at, is an InputError."""
    import dask
    from distributed import Client, LocalCluster

    if target is not None and workers is not None:
        raise InputError("give either a scheduler (an address or a Client) or a number of "
                         "local workers, not both.")
    if isinstance(target, Client):
        yield target
        return
    if isinstance(target, str):
        _check_address(target)
        try:
            client = Client(target, timeout=CONNECT_TIMEOUT)
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler at {target}: {exc}. Start one "
                             "(dask scheduler) or check the address.") from None
        with client:
            yield client
        return
    if target is not None:
        raise InputError(f"a cluster must be a distributed.Client or a scheduler address, "
                         f"got {target!r}.")
    if workers is None or workers < 1:
        raise InputError(f"the number of local workers must be >= 1, got {workers!r}.")
    # workers ignore Ctrl-C once started (`worker_setup`, also for one the nanny restarts
    # later; the user's configured preloads too)
    preload = [*dask.config.get("distributed.worker.preload", []),
               "jampacked.core.worker_setup"]
    with _hold_interrupt() as take_held:
        # silence_logs: the nanny's warnings at shutdown (a worker still busy in numba is
        # killed after a few seconds) are not the user's concern
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=logging.ERROR,
                               preload=preload)
        with cluster, Client(cluster) as client:
            take_held()  # a Ctrl-C of the start, here, where the cluster closes after it
            yield client


@contextlib.contextmanager
def _hold_interrupt() -> Iterator[Callable[[], None]]:
    """Hold a Ctrl-C of the seconds the local cluster takes to start, and give it to this
    process's own handler once it has started. SIGINT was ignored then, so that the worker
    processes starting inherited it ignored, and a Ctrl-C was lost: the run went on to its
    end. Now a handler records it, or it stays pending (SIGINT is blocked in this thread,
    and in the threads the cluster starts) until ``take_held()``, which puts the handler
    back and gives it what was held: call it where what was started is closed should that
    handler raise (it runs on leaving, if not called before). Worker processes do not keep
    the block (multiprocessing's spawn resets it): one still starting when the Ctrl-C comes
    may print a KeyboardInterrupt traceback as it stops, before its preload (`worker_setup`)
    ignores SIGINT. Main thread only."""
    if threading.current_thread() is not threading.main_thread():
        yield lambda: None
        return
    held: list[int] = []
    before = signal.signal(signal.SIGINT, lambda signum, frame: held.append(signum))
    blocks = hasattr(signal, "pthread_sigmask")  # POSIX
    if blocks:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    taken = False

    def take_held() -> None:
        nonlocal taken
        if taken:
            return
        taken = True
        # None: a handler not set from Python (an embedding host), which cannot be put back
        signal.signal(signal.SIGINT, signal.default_int_handler if before is None else before)
        if blocks:  # a Ctrl-C pending meanwhile reaches that handler now
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        if held:  # one another thread took meanwhile: to that handler too
            signal.raise_signal(signal.SIGINT)

    try:
        yield take_held
    finally:
        take_held()
