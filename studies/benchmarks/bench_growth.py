"""How the cost of the complete study grows: points, batch size, cores, and a Dask cluster.

The route is the slowest and most important one: the complete RV-40E-121 study at
no load (studies/rv40e_121_full.toml: 15 tolerances with the bearing clearances),
each reducer evaluated as `rvte mc` and `rvte sobol` evaluate it (the TE curve,
then the windup test), rows from the study's own Monte Carlo sampler.  Measured here,
in one run:

1. time per reducer against points per output revolution (720 ... 12 480), one core;
2. time per reducer against batch size (reducers solved together), one core, at the
   study's 3200 points;
3. throughput on one and two cores: one process on one thread; one process on two
   threads (the compiled iteration's threads, RVTE_THREADS); two worker processes
   (`--processes 2`); a Dask LocalCluster of two single-threaded workers;
4. the Dask scheduler's cost per batch on the LocalCluster: a round trip of tasks that
   carry a batch's rows and results and compute nothing;
5. the projected wall time of the complete study (N = 1024: 17 408 reducers) on a Dask
   cluster of 16, 64 and 256 workers.

The projection's model: the study's reducers come in batches of its batch size (64);
a worker evaluates one batch at a time at the per-worker throughput measured on two
Dask workers here (r, reducers/s: two workers on two cores, so shared caches and memory
are in it), and each batch costs the scheduler round trip o measured in 4 on top; the
batches are spread evenly, so W workers take ceil(batches / W) rounds:

    T(W) = start-up + ceil(batches / W) * (batch_size / r + o)

with the start-up the measured one of the two-worker LocalCluster (a real cluster's
workers start in parallel and load the same kernels).  What it leaves out: the
network between machines (a batch's rows and results are a few kB) and workers
slower or faster than this machine's cores.

    python studies/benchmarks/bench_growth.py [--reducers 4] [--quick]

--quick: 720 ... 3200 points only and batch sizes up to 4 (about two minutes).
"""

import os

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "rv40e_121_full.toml"
FULL_REDUCERS = 17_408  # N = 1024, 15 groups: N (G + 2)
WORKERS = (16, 64, 256)


def timed(work):
    work()  # untimed: the kernels load, the batch's first arrays
    start = time.perf_counter()
    work()
    return time.perf_counter() - start


def per_reducer(study, X):
    from tolerance.evaluate import evaluate

    return timed(lambda: evaluate(study, X)) / X.shape[0]


def backend_rate(study, X, backend):
    """(start-up s, reducers/s) of a backend over X in the study's batches, after a warm-up batch
    per worker (the same measure as bench_study.py)."""
    from tolerance.store import JobStore, open_output

    B = study.batch_size
    spans = [(s, min(s + B, X.shape[0])) for s in range(0, X.shape[0], B)]
    with tempfile.TemporaryDirectory() as tmp:
        store = JobStore(open_output(study, Path(tmp)), study, "bench")
        t0 = time.perf_counter()
        with backend:
            warm = spans[: backend.workers]
            for (s, e), Xb, Y, ok in backend.map(study, ((b, X[b[0] : b[1]]) for b in warm)):
                store.write(s, e, Xb, Y, ok)
            t1 = time.perf_counter()
            rest = spans[backend.workers :]
            for (s, e), Xb, Y, ok in backend.map(study, ((b, X[b[0] : b[1]]) for b in rest)):
                store.write(s, e, Xb, Y, ok)
            t2 = time.perf_counter()
    return t1 - t0, sum(e - s for s, e in rest) / (t2 - t1)


def _echo(X):
    return np.zeros((X.shape[0], 3)), np.ones(X.shape[0], dtype=bool)


def scheduler_round_trip(batch_rows, columns, tasks=200):
    """Seconds per task of a Dask LocalCluster of two workers for tasks that carry a batch's
    rows and results and compute nothing, submitted as the study's backend submits them."""
    import dask
    from dask.distributed import Client, LocalCluster, wait

    from tolerance.backends import DASK_LOCAL_CONFIG

    X = np.random.default_rng(0).random((batch_rows, columns))
    with dask.config.set(DASK_LOCAL_CONFIG):
        with (
            LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            Client(cluster) as client,
        ):
            wait([client.submit(_echo, X, pure=False) for _ in range(10)])
            start = time.perf_counter()
            futures = [client.submit(_echo, X, pure=False) for _ in range(tasks)]
            for future in futures:
                future.result()
            return (time.perf_counter() - start) / tasks


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reducers", type=int, default=4, help="reducers per point count")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()

    from tolerance import montecarlo
    from tolerance.backends import DaskBackend, InProcess, Processes
    from tolerance.study import load_study

    study = load_study(STUDY)
    os.environ["RVTE_THREADS"] = "1"
    print(
        f"study {STUDY.name}: {study.design.name}, {len(study.columns)} columns, "
        f"{study.points} points, batches of {study.batch_size}; load average "
        f"{os.getloadavg()[0]:.2f}"
    )

    print(f"\n1. points per output revolution (one core, {args.reducers} reducers, TE curve and windup test)")
    print(f"{'points':>8}{'s/reducer':>11}{'reducers/s':>12}{'us/point':>10}{'ratio':>8}")
    X = montecarlo.rows(study, 0, args.reducers)
    base = None
    for points in (720, 1600, 3200) + (() if args.quick else (6400, 12480)):
        t = per_reducer(replace(study, points=points), X)
        base = base or t
        print(f"{points:>8}{t:>11.3f}{1 / t:>12.2f}{t / points * 1e6:>10.1f}{t / base:>8.2f}")

    print(f"\n2. batch size (one core, {study.points} points)")
    print(f"{'batch':>8}{'s/reducer':>11}{'reducers/s':>12}{'ratio':>8}")
    base = None
    for size in (1, 4) + (() if args.quick else (16, 64)):
        t = per_reducer(study, montecarlo.rows(study, 0, size))
        base = base or t
        print(f"{size:>8}{t:>11.3f}{1 / t:>12.2f}{t / base:>8.2f}")

    count = 8 if args.quick else 16
    small = replace(study, batch_size=count // 2)
    X = montecarlo.rows(study, 0, count * 2)
    print(
        f"\n3. cores ({X.shape[0]} reducers in batches of {small.batch_size}, "
        f"{study.points} points; a warm-up batch per worker is not timed)"
    )
    print(f"{'how':<30}{'cores':>6}{'start-up s':>12}{'reducers/s':>12}{'per core':>10}{'ratio':>8}")
    runs = []
    for label, cores, threads, make in (
        ("one process, one thread", 1, "1", InProcess),
        ("one process, two threads", 2, "2", InProcess),
        ("two processes", 2, "1", lambda: Processes(2)),
        ("Dask LocalCluster, 2 workers", 2, "1", lambda: DaskBackend(workers=2)),
    ):
        os.environ["RVTE_THREADS"] = threads
        start, rate = backend_rate(small, X, make())
        runs.append((label, cores, start, rate))
    os.environ["RVTE_THREADS"] = "1"
    base = runs[0][3]
    for label, cores, start, rate in runs:
        print(
            f"{label:<30}{cores:>6}{start:>12.1f}{rate:>12.2f}{rate / cores:>10.2f}"
            f"{rate / cores / base:>8.2f}"
        )

    trip = scheduler_round_trip(study.batch_size, len(study.columns))
    print(
        f"\n4. Dask scheduler round trip per batch (LocalCluster, 2 workers, empty tasks with "
        f"a batch's {study.batch_size} rows): {trip * 1e3:.2f} ms"
    )

    dask_start, dask_rate = runs[3][2], runs[3][3] / 2
    batches = math.ceil(FULL_REDUCERS / study.batch_size)
    batch_s = study.batch_size / dask_rate
    print(
        f"\n5. projected complete study (N = 1024: {FULL_REDUCERS} reducers, {batches} batches "
        f"of {study.batch_size}): r = {dask_rate:.2f} reducers/s per worker, a batch "
        f"{batch_s:.1f} s + {trip * 1e3:.1f} ms, start-up {dask_start:.1f} s"
    )
    print(f"{'workers':>8}{'rounds':>8}{'wall':>12}")
    for workers in (1, 2) + WORKERS:
        rounds = math.ceil(batches / workers)
        wall = dask_start + rounds * (batch_s + trip)
        print(f"{workers:>8}{rounds:>8}{wall / 60:>10.1f} min")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
