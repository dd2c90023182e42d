"""Benchmark: the allocation search's surrogate, its chaos as a quadratic form against its terms.

The search (`tolerance.least_cost.allocate_scales`) evaluates the surrogate's yield and
its gradient at every step of its optimisers: the probability that a reducer passes, on
YIELD_DRAWS unit draws, through a degree-2 polynomial chaos of the metric's mean and one
of its log variance (`tolerance.surrogate`).  A chaos of degree 2 is a quadratic form,
k0 + g.x + x.Q x (`Chaos.quadratic`), evaluated with two BLAS products; the sum over its
orthonormal Legendre terms (`Chaos.terms`, `Chaos.terms_value_gradient`) is the
reference and stays the route of higher degrees.  This script times both on a chaos
fitted by LARS to a noisy quadratic of --inputs inputs, at the search's YIELD_DRAWS rows,
and prints the largest difference between them.

With --allocation it also runs the allocation of the RV-40E-121 rated study at 36 points
(the one tests/test_allocate_rv40e.py checks; 2 worker processes) twice in this process,
once with the chaos summed term by term, and prints the wall time, the model evaluations
and the allocated cost of each.

    python studies/benchmarks/bench_surrogate.py [--inputs 15] [--repeat 20] [--allocation]
"""

import argparse
import re
import shutil
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from bench_roller_law import best_of  # this folder: the script's own

from tolerance.least_cost import YIELD_DRAWS, Limit
from tolerance.surrogate import Chaos, Surrogate

ROOT = Path(__file__).resolve().parents[2]


def flat(result) -> np.ndarray:
    """An array, or a tuple of arrays, as one flat array."""
    parts = result if isinstance(result, tuple) else (result,)
    return np.concatenate([np.ravel(part) for part in parts])


@contextmanager
def terms_only():
    """Chaos evaluated term by term (the reference) while inside."""
    kept = Chaos.__call__, Chaos.value_gradient
    Chaos.__call__, Chaos.value_gradient = Chaos.terms, Chaos.terms_value_gradient
    try:
        yield
    finally:
        Chaos.__call__, Chaos.value_gradient = kept


def kernels(inputs: int, repeat: int) -> None:
    rng = np.random.default_rng(3)
    Z = rng.uniform(0.0, 2.0, (3000, inputs))
    weights = rng.normal(0.0, 0.3, inputs)
    g = Z @ weights + 0.2 * Z[:, 0] * Z[:, 1] - 0.1 * Z[:, 2] ** 2
    Y = np.exp(g + 0.1 * (1.0 + Z[:, :1].ravel()) * rng.standard_normal(3000))[:, None]
    surrogate = Surrogate(Z, Y, (Limit(0, float(np.quantile(Y, 0.9)), "max"),))
    _, mean, *_ = surrogate.fits[0]
    X = rng.uniform(-1.0, 1.0, (YIELD_DRAWS, inputs))
    at = rng.uniform(0.0, 2.0, (YIELD_DRAWS, inputs))
    print(f"# bench_surrogate: a degree-2 chaos of {inputs} inputs, {mean.alpha.shape[0]} terms kept by LARS")
    print("| what | rows | reference [ms] | quadratic form [ms] | ratio | largest difference |")
    print("|---|---|---|---|---|---|")
    for what, fast, slow in (
        ("chaos values", lambda: mean(X), lambda: mean.terms(X)),
        ("chaos values and gradient", lambda: mean.value_gradient(X), lambda: mean.terms_value_gradient(X)),
    ):
        a, b = flat(fast()), flat(slow())
        t_fast, t_slow = best_of(fast, repeat), best_of(slow, repeat)
        print(
            f"| {what} | {YIELD_DRAWS} | {1e3 * t_slow:.2f} | {1e3 * t_fast:.2f} | {t_slow / t_fast:.1f} | "
            f"{np.abs(a - b).max():.1e} |"
        )
    fast_p = surrogate.probability(at, gradient=True)
    t_fast = best_of(lambda: surrogate.probability(at, gradient=True), repeat)
    with terms_only():
        slow_p = surrogate.probability(at, gradient=True)
        t_slow = best_of(lambda: surrogate.probability(at, gradient=True), repeat)
    difference = max(np.abs(fast_p[0] - slow_p[0]).max(), np.abs(fast_p[1] - slow_p[1]).max())
    print(
        f"| surrogate probability and gradient (mean and log variance) | {YIELD_DRAWS} | {1e3 * t_slow:.2f} | "
        f"{1e3 * t_fast:.2f} | {t_slow / t_fast:.1f} | {difference:.1e} |"
    )


def allocation() -> None:
    import tolerance

    text = (ROOT / "studies" / "rv40e_121_full_rated.toml").read_text()
    for key, value in dict(name='"rv40e_121_full_rated_36"', points=36, output='"output"').items():
        text, count = re.subn(rf"(?m)^{key}\s*=.*$", f"{key} = {value}", text)
        assert count == 1, key
    print()
    print("# the RV-40E-121 rated study at 36 points, yield >= 0.95, 2 worker processes, fresh folders")
    print("| chaos evaluated | wall [s] | model evaluations | cost allocated | ratio to the reference |")
    print("|---|---|---|---|---|")
    rows = []
    for label, context in (("term by term (reference)", terms_only), ("quadratic form", _nothing)):
        folder = Path(tempfile.mkdtemp(prefix="bench_surrogate_"))
        try:
            path = folder / "study.toml"
            path.write_text(text)
            with context():
                start = time.perf_counter()
                result = tolerance.allocate(path, 0.95, progress=False, processes=2)
                wall = time.perf_counter() - start
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        rows.append((label, wall, result.model_evaluations, result.total_cost_allocated))
    for label, wall, evaluations, cost in rows:
        print(f"| {label} | {wall:.1f} | {evaluations} | {cost:.4f} | {rows[0][1] / wall:.2f} |")


@contextmanager
def _nothing():
    yield


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=15)
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--allocation", action="store_true")
    args = parser.parse_args(argv)
    kernels(args.inputs, args.repeat)
    if args.allocation:
        allocation()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
