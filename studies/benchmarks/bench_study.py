"""Benchmark: evaluations per second of the whole tolerance-study pipeline, by backend.

The pipeline is what `rvte sobol` does per batch: take the rows of the Saltelli
matrix of studies/rv40e_121_sobol.toml (RV-40E-121, all 8 seed-002 error
sources, 720 points per output revolution, no load), turn them into reducers,
solve them, and write each batch to a Parquet store.  Measured:

- in-process (the baseline, one core);
- 2 local worker processes (`--processes 2`);
- a Dask LocalCluster of 1 and of 2 single-threaded workers (`--workers N`).

For each: the start-up (cluster or pool start plus one warm-up batch per
worker, untimed in the throughput) and the steady throughput over the other
batches, best of --repeats interleaved rounds (the machine may be shared);
"per core" divides by the number of workers, and the ratio is that
per-core throughput against the in-process one.  Two processes on this
machine's two cores do not each run as fast as one alone (shared caches and
memory bandwidth, other load), so the benchmark also runs two independent
in-process runs at the same time: the Dask overhead per core (target: at most
10 %) is 1 worker against in-process, and 2 workers against those two runs.
Then the projected time of the full study (N = 1024 base samples: 10 240 TE
curves) on the fastest backend, and, without --quick, the measured time of
that full study run end to end by `tolerance.run_sobol` on 2 Dask workers
(target: at most 10 minutes).  On a shared machine the numbers move by 10 %
from run to run: the load average is printed before and after.

    python studies/benchmarks/bench_study.py [--quick] [--batches K] [--repeats R]

--quick: 6 timed batches of 64 per backend (about two minutes with the default
2 rounds); default 12, plus the full study (about six minutes in all).  BLAS
runs on one thread everywhere, so per core is per core.
"""

import os
import sys

for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "RVTE_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import multiprocessing  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

from tolerance import run_sobol, sobol  # noqa: E402
from tolerance.backends import DaskBackend, InProcess, Processes  # noqa: E402
from tolerance.store import JobStore, open_output  # noqa: E402
from tolerance.study import load_study  # noqa: E402

STUDY = Path(__file__).resolve().parents[1] / "rv40e_121_sobol.toml"
FULL_TARGET_S = 600.0  # the full Sobol study on this 2-core machine
OVERHEAD_TARGET = 0.90  # per-core throughput of Dask against in-process


def measure(study, X, backend, folder, batches):
    """(start-up s, steady rows/s) of `backend` over `batches` timed batches after a warm-up."""
    B = study.batch_size
    store = JobStore(open_output(study, folder), study, "bench")
    warm = backend.workers
    spans = [(s, s + B) for s in range(0, (warm + batches) * B, B)]
    t0 = time.perf_counter()
    with backend:
        for (s, e), Xb, Y, conv in backend.map(study, ((b, X[b[0] : b[1]]) for b in spans[:warm])):
            store.write(s, e, Xb, Y, conv)
        t1 = time.perf_counter()
        for (s, e), Xb, Y, conv in backend.map(study, ((b, X[b[0] : b[1]]) for b in spans[warm:])):
            store.write(s, e, Xb, Y, conv)
        t2 = time.perf_counter()
    return t1 - t0, batches * B / (t2 - t1)


def _alone(folder, batches):
    """In a fresh process: the in-process steady throughput (rows/s), for the two-at-once reference."""
    study = load_study(STUDY)
    X = sobol.sample(study.problem(), study.sobol_n, study.second_order, seed=study.seed)
    return measure(study, X, InProcess(), Path(folder), batches)[1]


def two_at_once(folder, batches):
    """Summed throughput of two independent in-process runs at the same time: what two cores
    of this machine give with no framework at all (shared caches, memory, other load)."""
    with ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        runs = [pool.submit(_alone, Path(folder) / f"alone{k}", batches) for k in range(2)]
        return sum(run.result() for run in runs)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 timed batches, no full study")
    parser.add_argument("--batches", type=int, default=None, help="timed batches per backend")
    parser.add_argument("--repeats", type=int, default=2, help="rounds over the backends (best of)")
    args = parser.parse_args(argv)
    batches = args.batches or (6 if args.quick else 12)

    study = load_study(STUDY)
    X = sobol.sample(study.problem(), study.sobol_n, study.second_order, seed=study.seed)
    print(
        f"study {STUDY.name}: {study.design.name}, {len(study.groups)} factors, "
        f"{len(study.columns)} columns, {study.points} points/rev, load {study.load_Nm:g} N*m, "
        f"batches of {study.batch_size}; {batches} timed batches per backend, best of "
        f"{args.repeats}; load average before: {os.getloadavg()[0]:.2f}"
    )
    backends = [
        ("in-process", InProcess),
        ("2 processes", lambda: Processes(2)),
        ("Dask, 1 worker", lambda: DaskBackend(workers=1)),
        ("Dask, 2 workers", lambda: DaskBackend(workers=2)),
    ]
    best = {}
    with tempfile.TemporaryDirectory() as tmp:
        for repeat in range(args.repeats):  # interleaved, best of: other load on the machine
            for k, (label, make) in enumerate(backends):
                backend = make()
                start, rate = measure(study, X, backend, Path(tmp) / f"b{repeat}-{k}", batches)
                old = best.get(label, (backend.workers, float("inf"), 0.0))
                best[label] = (backend.workers, min(old[1], start), max(old[2], rate))
            pair = two_at_once(Path(tmp) / f"pair{repeat}", batches)
            best["pair"] = max(best.get("pair", 0.0), pair)
    rows = [(label, *best[label]) for label, _ in backends]
    base = rows[0][3]
    print()
    print(f"{'backend':<17}{'workers':>8}{'start-up s':>12}{'curves/s':>10}{'per core':>10}{'ratio':>8}")
    for label, workers, start, rate in rows:
        print(
            f"{label:<17}{workers:>8}{start:>12.1f}{rate:>10.1f}{rate / workers:>10.1f}"
            f"{rate / workers / base:>8.2f}"
        )
    total = X.shape[0]
    fastest = max(rows, key=lambda r: r[3])
    projected = fastest[2] + total / fastest[3]
    print(
        f"\nfull study N = {study.sobol_n}: {total} curves; projected on {fastest[0]}: "
        f"{projected:.0f} s (target <= {FULL_TARGET_S:.0f} s)"
    )
    print(
        f"{'2 in-process runs at once (no framework)':<41}{best['pair']:>10.1f}"
        f"{best['pair'] / 2:>10.1f}{best['pair'] / 2 / base:>8.2f}   <- what 2 cores give here"
    )
    one = next(r for r in rows if r[0] == "Dask, 1 worker")
    two = next(r for r in rows if r[0] == "Dask, 2 workers")
    print(
        f"Dask overhead per core: 1 worker against in-process {1 - one[3] / base:+.0%}; 2 workers "
        f"against 2 in-process runs at once {1 - two[3] / best['pair']:+.0%} "
        f"(target <= {1 - OVERHEAD_TARGET:.0%})"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f} (2 cores; above ~0.3 other work shares them)")
    if not args.quick:
        with tempfile.TemporaryDirectory() as tmp:
            t = time.perf_counter()
            result = run_sobol(STUDY, output=Path(tmp) / "full", workers=2, plots=True)
            seconds = time.perf_counter() - t
        ind = result.analyses["te_pp_arcsec"].indices
        print(
            f"full study run by run_sobol on 2 Dask workers: {seconds:.0f} s end to end "
            f"(target <= {FULL_TARGET_S:.0f} s); te_pp ranking: "
            + ", ".join(ind.names[g] for g in ind.ranking()[:3])
            + ", ..."
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
