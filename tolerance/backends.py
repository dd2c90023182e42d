"""Where the batches of a study are evaluated: in this process, in worker processes, or on Dask.

Evaluating a batch is one pure function (`tolerance.evaluate.evaluate`) of the
study and the batch's sample rows, and the batch boundaries are fixed by the
study, not by the backend, so every backend computes bit-for-bit the same
numbers (the solver's result for a reducer depends, at round-off level, on
the batch it is solved in; the boundaries are therefore never changed).

- `InProcess()`: the default; the core is vectorised over the batch already.
- `Processes(n)`: n local worker processes (spawned, one BLAS thread each).
- `DaskBackend(workers=n)`: a Dask LocalCluster of n single-threaded worker
  processes; `DaskBackend(scheduler="tcp://host:port")`: an existing Dask
  cluster whose workers have the same rvte installed (checked: a worker with
  another model version is refused).

Each backend is a context manager with `map(study, tasks)`: tasks are
((start, stop), X) pairs, consumed lazily with a bounded number in flight, and
results come back as they complete, so that the caller writes each batch the
moment it is done.  Leaving it on an error or on Ctrl-C ends the workers at
once (the batches in flight are dropped; their workers ignore Ctrl-C, so that
only this process reacts to it, `spawning`).  A scheduler address is checked
when the backend is made, before any work (`scheduler_address`).
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import traceback
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from rvfmu.core.base.checks import InputError, integer

from .evaluate import evaluate
from .study import model_fingerprint

IN_FLIGHT_PER_WORKER = 3  # keeps every worker busy while the next batch's rows travel
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
DASK_LOCAL_CONFIG = {
    # Dask's default MALLOC_TRIM_THRESHOLD_=65536 turns glibc's adaptive mmap threshold off,
    # and the solver's many temporary arrays then cost an mmap/munmap each (measured:
    # 88 -> 51 TE curves/s on one core): not set in our workers.
    "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
    # The statistical profiler samples the computing thread every 10 ms (GIL); no dashboard
    # reads it here (measured, paired runs on 1 worker: 0.92 -> 1.0 of in-process speed).
    "distributed.worker.profile.enabled": False,
    # Batches take ~1 s: the scheduler, nannies and client need not look around every
    # 20-500 ms, and uniform batches need no work stealing.  Halves the CPU that this
    # process takes from the workers on a small machine (measured: 12 % -> 5 % of a core).
    "distributed.admin.tick.interval": "500ms",
    "distributed.worker.memory.monitor-interval": "2s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.scheduler.work-stealing": False,
}


def evaluate_checked(study, X, fingerprint):
    """`evaluate` on a worker, refusing to run if the worker's model code differs from the caller's."""
    if fingerprint != model_fingerprint():
        raise RuntimeError(
            "a worker runs another version of rvte's model than this process "
            f"(model hash {model_fingerprint()[:12]} there, {fingerprint[:12]} here); "
            "install the same rvte on every worker"
        )
    return evaluate(study, X)


class InProcess:
    """Evaluate the batches one after another in this process."""

    workers = 1

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def describe(self) -> str:
        """The backend as the run summary names it: "in-process"."""
        return "in-process"

    def map(self, study, tasks):
        """Evaluate each (batch, X) of `tasks` here, in order; yield (batch, X, Y, converged)
        with Y (rows, M) and converged (rows,) from `evaluate`."""
        for batch, X in tasks:
            Y, converged = evaluate(study, X)
            yield batch, X, Y, converged


def _warm_up():
    """Run in each new worker: load the model's modules before the first batch arrives."""
    return model_fingerprint()


def _follow_parent(parent: int) -> None:
    """Run in each new worker: leave Ctrl-C to the parent, exit when the parent is gone.

    Ctrl-C in a terminal interrupts every process of the foreground group: a
    worker would die printing its own traceback in the middle of a batch, while
    the parent, which keeps the finished batches, ends its workers anyway
    (`stop_pool`).  A pool's workers wait on their queue for ever if the main
    process is killed (SIGTERM, SIGKILL: no clean-up runs), each holding a
    core's worth of memory; this thread ends them within a second of their parent.
    """
    import signal
    import threading
    import time

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch():
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(3)

    threading.Thread(target=watch, name="follow-parent", daemon=True).start()


def local_pool(workers: int) -> ProcessPoolExecutor:
    """Spawned worker processes, one BLAS thread each, that end with the process that made them.

    The workers start at the first tasks submitted: submit those under `spawning()`.
    """
    # Spawned children inherit the environment at their start, before numpy loads.
    with _environment(ONE_THREAD):
        return ProcessPoolExecutor(
            workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_follow_parent,
            initargs=(os.getpid(),),
        )


@contextlib.contextmanager
def spawning():
    """Start worker processes in here: one BLAS thread each, and deaf to Ctrl-C.

    Ctrl-C in a terminal interrupts every process of the foreground group; a
    worker would die printing its own traceback in the middle of a batch, while
    this process, which keeps the finished batches, ends its workers anyway
    (`stop_pool`, `DaskBackend.__exit__`).  A signal mask is inherited through
    fork and exec, so a worker started while SIGINT is blocked never receives
    it, from its first instruction on; here the interrupt is held until the
    block ends (or taken by another thread of this process at once).
    """
    with _environment(ONE_THREAD), _sigint_blocked():
        yield


@contextlib.contextmanager
def _sigint_blocked():
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def stop_pool(pool: ProcessPoolExecutor, abort: bool) -> None:
    """Shut a local pool down: after its running tasks, or with `abort` (an error or Ctrl-C
    in this process) at once, its workers ended without finishing their batch (it is not
    kept: only whole batches are written)."""
    with _no_interrupts():
        if abort:
            for process in list((getattr(pool, "_processes", None) or {}).values()):
                with contextlib.suppress(Exception):
                    process.terminate()
        pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def _no_interrupts():
    """Ctrl-C ignored while workers are being ended: a second one must not leave them running."""
    import signal
    import threading

    previous = signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or previous is None:
        yield  # None: no handler set from Python (the interpreter is shutting down)
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class Processes:
    """A pool of `workers` spawned local processes, one BLAS thread each."""

    def __init__(self, workers: int):
        self.workers = integer("processes", workers, 1, 256)
        self._pool = None

    def describe(self) -> str:
        """The backend as the run summary names it: the number of worker processes."""
        return f"{self.workers} worker processes"

    def __enter__(self):
        # start them all now, with one BLAS thread each
        self._pool = local_pool(self.workers)
        with spawning():
            starts = [self._pool.submit(_warm_up) for _ in range(self.workers)]
            try:
                for start in starts:
                    start.result()
            except BrokenProcessPool as exc:
                self.__exit__(type(exc))
                raise RuntimeError(_DIED.format(exc=exc)) from None
            except BaseException as exc:  # Ctrl-C while they start: end them too
                self.__exit__(type(exc))
                raise
        return self

    def __exit__(self, exc_type=None, *exc):
        if self._pool is not None:
            pool, self._pool = self._pool, None
            stop_pool(pool, abort=exc_type is not None)
        return False

    def map(self, study, tasks):
        """Evaluate the (batch, X) of `tasks` on the workers, a few in flight per worker; yield
        (batch, X, Y, converged) as each finishes (any order).  A worker running other model
        code, or a dead pool, raises RuntimeError."""
        fingerprint = model_fingerprint()
        try:
            yield from _windowed(
                tasks,
                self.workers,
                lambda X: self._pool.submit(evaluate_checked, study, X, fingerprint),
                _wait_futures,
            )
        except BrokenProcessPool as exc:
            raise RuntimeError(_DIED.format(exc=exc)) from None

    def calls(self, function, arguments, chunksize: int = 1):
        """function(*args) for each args of `arguments` on the workers; yield the results in
        order (for work that is not one study's batches: the allocation's training groups,
        each a study of its own).  A dead pool raises RuntimeError."""
        try:
            yield from self._pool.map(function, *zip(*arguments), chunksize=chunksize)
        except BrokenProcessPool as exc:
            raise RuntimeError(_DIED.format(exc=exc)) from None


_DIED = (
    "a worker process died ({exc}); finished batches are kept. A script that uses worker "
    "processes must run its main code under `if __name__ == '__main__':`"
)


class _CancelBeforeStart(logging.Filter):
    """Drops the one traceback distributed (2026.8) logs when Ctrl-C lands in `sync()` before
    its coroutine has made the future that the interrupt's `cancel()` callback cancels: a
    NameError on that unset name in distributed/utils.py's `cancel`, logged by tornado from
    the event loop's thread (an older release set the name to None first).  Nothing was
    running to cancel, so the run's own interrupt line stays the whole story."""

    def filter(self, record):
        exc = record.exc_info[1] if record.exc_info else None
        if not isinstance(exc, NameError) or exc.__traceback__ is None:
            return True
        last = traceback.extract_tb(exc.__traceback__)[-1]
        return not (last.name == "cancel" and Path(last.filename).match("distributed/utils.py"))


def quiet_cancel_before_start() -> None:
    """`_CancelBeforeStart` on tornado's logger, once per process and for good: the interrupt's
    callback may run after the backend has closed."""
    logger = logging.getLogger("tornado.application")
    if not any(isinstance(f, _CancelBeforeStart) for f in logger.filters):
        logger.addFilter(_CancelBeforeStart())


class DaskBackend:
    """Dask distributed: a LocalCluster of `workers` processes, or the cluster at `scheduler`."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None):
        if (workers is None) == (scheduler is None):
            raise InputError(
                "dask",
                {"workers": workers, "scheduler": scheduler},
                "give either a number of local workers or a scheduler address",
            )
        self.n_local = None if workers is None else integer("workers", workers, 1, 256)
        self.scheduler = None if scheduler is None else scheduler_address(scheduler)
        self.client = self.cluster = None
        self.workers = self.n_local or 1

    def describe(self) -> str:
        """The backend as the run summary names it: the scheduler and its workers, or the
        LocalCluster's size."""
        if self.scheduler:
            return f"Dask cluster at {self.scheduler} ({self.workers} workers)"
        return f"Dask LocalCluster of {self.n_local} workers"

    def __enter__(self):
        import dask
        from dask.distributed import Client, LocalCluster

        quiet_cancel_before_start()
        try:
            if self.scheduler:
                self.client = Client(self.scheduler, timeout="20s")
                self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))
            else:
                # BLAS threads: Dask's nanny sets OMP/OPENBLAS/MKL_NUM_THREADS=1 in its
                # workers (distributed.nanny.pre-spawn-environ); they are set here too.
                # Deaf to Ctrl-C as `spawning` makes a pool's workers; the nannies start
                # theirs from Dask's own threads, which no signal mask of this thread
                # reaches, so SIGINT is ignored (inherited by every child) while the
                # cluster starts: a Ctrl-C in those seconds is lost, press it again.
                with dask.config.set(DASK_LOCAL_CONFIG), _no_interrupts():
                    self.cluster = LocalCluster(
                        n_workers=self.n_local,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=None,
                        silence_logs=logging.ERROR,
                        env=dict(ONE_THREAD),
                    )
                    self.client = Client(self.cluster)
        except OSError as exc:
            self.__exit__()
            where = self.scheduler or "a LocalCluster"
            raise RuntimeError(f"could not reach the Dask scheduler at {where}: {exc}") from None
        except BaseException:  # Ctrl-C while the cluster starts: close it too
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc):
        with _no_interrupts():
            for thing in (self.client, self.cluster):
                if thing is not None:
                    with contextlib.suppress(Exception):
                        thing.close()
        self.client = self.cluster = None
        return False

    def map(self, study, tasks):
        """Evaluate the (batch, X) of `tasks` on the Dask workers (the study sent once), a few
        in flight per worker; yield (batch, X, Y, converged) as each finishes (any order)."""
        from dask.distributed import wait as dask_wait

        remote_study = self.client.scatter(study, broadcast=True, hash=False)  # own key per map
        fingerprint = model_fingerprint()

        def submit(X):
            return self.client.submit(evaluate_checked, remote_study, X, fingerprint, pure=False)

        def wait_any(futures):
            done = dask_wait(list(futures), return_when="FIRST_COMPLETED").done
            return done

        yield from _windowed(tasks, self.workers, submit, wait_any)


# The address forms of a Dask scheduler that `dask.distributed.Client` connects to
# (distributed.comm.addressing.parse_address: a scheme of distributed.comm.registry,
# default tcp, then host:port; "inproc://" reaches a scheduler in this very process).
NETWORK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
SCHEDULER_FORMS = (
    "tcp://HOST:PORT, HOST:PORT (tcp), tls://HOST:PORT, ws://HOST:PORT, "
    "wss://HOST:PORT or ucx://HOST:PORT, PORT from 1 to 65535 (IPv6 hosts in "
    "brackets: tcp://[::1]:8786), or inproc://... of a scheduler in this process"
)


def scheduler_address(value, field: str = "--scheduler") -> str:
    """`value` as a Dask scheduler address, checked before anything starts; InputError naming
    `field`, the value and SCHEDULER_FORMS otherwise (Dask's own error, "missing port
    number", names neither the option nor what it accepts)."""
    text = value.strip() if isinstance(value, str) else None
    if not text:
        raise InputError(field, value, f"must be a Dask scheduler address: {SCHEDULER_FORMS}")
    scheme, _, location = text.rpartition("://")
    scheme = scheme.lower() or "tcp"
    if scheme == "inproc" and location:
        return text
    host, _, port = location.rpartition(":")
    if host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    fine = (
        scheme in NETWORK_SCHEMES
        and host
        and not any(c in host for c in "/[] ")
        and port.isdigit()
        and 1 <= int(port) <= 65535
    )
    if not fine:
        raise InputError(field, value, f"is not a Dask scheduler address: {SCHEDULER_FORMS}")
    return text


def _wait_futures(futures):
    return wait(list(futures), return_when=FIRST_COMPLETED).done


def _windowed(tasks, workers, submit, wait_any):
    """Submit tasks with at most IN_FLIGHT_PER_WORKER * workers in flight; yield as they finish."""
    tasks = iter(tasks)
    pending = {}
    limit = IN_FLIGHT_PER_WORKER * workers

    def fill():
        while len(pending) < limit:
            try:
                batch, X = next(tasks)
            except StopIteration:
                return
            pending[submit(X)] = (batch, X)

    fill()
    try:
        while pending:
            for future in wait_any(pending):
                batch, X = pending.pop(future)
                Y, converged = future.result()
                yield batch, X, Y, converged
            fill()
    finally:
        for future in pending:
            future.cancel()


def make_backend(processes: int | None = None, workers: int | None = None, scheduler: str | None = None):
    """The backend the options ask for: none -> InProcess; processes -> Processes;
    workers and/or scheduler -> DaskBackend."""
    if processes is not None and (workers is not None or scheduler is not None):
        raise InputError(
            "processes",
            processes,
            "give either --processes or a Dask backend (--workers / --scheduler), not both",
        )
    if workers is not None and scheduler is not None:
        raise InputError(
            "workers",
            workers,
            "--workers starts a local Dask cluster; with "
            "--scheduler the cluster's own workers are used: give one of them",
        )
    if processes is not None:
        return Processes(processes)
    if workers is not None or scheduler is not None:
        return DaskBackend(workers=workers, scheduler=scheduler)
    return InProcess()


@contextlib.contextmanager
def _environment(values):
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
