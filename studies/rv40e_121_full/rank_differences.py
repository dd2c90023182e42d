"""Which neighbouring ranks of a stored Sobol run are settled: the bootstrap interval of the
difference of their total-order indices.

Each factor's own interval (what `rvte sobol` prints) overlaps its neighbour's long
before their order is in doubt: the two estimates come from the same rows and move
together, so what decides the order is the interval of their difference.  This reads a
stored Sobol job of a study, recomputes ST for every group by the estimator SALib uses
(Jansen's, on the output standardised over all rows: ST_i = E[(f(A) - f(AB_i))^2] /
(2 Var[f(A), f(B)])), resamples the base samples with replacement as SALib's bootstrap
does, and prints for each pair of neighbouring ranks the difference, the half-width of
its interval at 95 % (normal, from the resamples' spread, as SALib's intervals) and the
share of resamples that keep the order.

    python studies/rv40e_121_full/rank_differences.py [study.toml] [--n 2048] [--metric te_pp_arcsec]

The run must be stored (rvte sobol ... -n N) by the rvte version that reads it.
"""

import argparse
from pathlib import Path

import numpy as np
from scipy.stats import norm

from rvfmu.core.base.checks import InputError
from tolerance import load_study
from tolerance.frames import load_results

HERE = Path(__file__).resolve().parent


def total_order(A, B, AB):
    """(G,) Jansen's total-order estimates from f(A), f(B) (N,) and f(AB_i) (N, G)."""
    var = np.var(np.r_[A, B])
    return 0.5 * np.mean((A[:, None] - AB) ** 2, axis=0) / var


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", nargs="?", default=str(HERE.parent / "rv40e_121_full.toml"))
    parser.add_argument("--n", type=int, default=2048, help="base samples of the stored run")
    parser.add_argument("--metric", default="te_pp_arcsec")
    parser.add_argument("--resamples", type=int, default=2000)
    parser.add_argument("--confidence", type=float, default=0.95)
    args = parser.parse_args()

    try:
        study = load_study(args.study)
        frame = load_results(study.output, f"sobol-n{args.n}")
    except InputError as exc:
        raise SystemExit(f"error: {exc}") from None
    groups = list(dict.fromkeys(study.problem()["groups"]))  # SALib's order of the AB_i
    y = frame[args.metric].to_numpy()
    G = len(groups)
    if y.size != args.n * (G + 2):
        raise SystemExit(f"sobol-n{args.n} holds {y.size} rows, not {args.n * (G + 2)}: finish the run first")
    Y = ((y - y.mean()) / y.std()).reshape(args.n, G + 2)  # rows: A, AB_1 .. AB_G, B
    A, AB, B = Y[:, 0], Y[:, 1:-1], Y[:, -1]
    estimate = total_order(A, B, AB)
    rng = np.random.default_rng(0)
    boots = np.empty((args.resamples, G))
    for r in range(args.resamples):
        rows = rng.integers(args.n, size=args.n)
        boots[r] = total_order(A[rows], B[rows], AB[rows])
    z = norm.ppf(0.5 + args.confidence / 2)
    order = np.argsort(-estimate)
    print(
        f"{study.name}, {args.metric}, N = {args.n}: ST with {100 * args.confidence:g} % "
        f"intervals ({args.resamples} resamples)"
    )
    for rank, g in enumerate(order, 1):
        print(f"  {rank:2d}  {groups[g]:<26} {estimate[g]:.3f} ± {z * boots[:, g].std():.3f}")
    print("neighbouring ranks: ST difference, its interval's half-width, resamples that keep the order")
    for upper, lower in zip(order[:-1], order[1:]):
        spread = boots[:, upper] - boots[:, lower]
        difference = estimate[upper] - estimate[lower]
        half = z * spread.std()
        verdict = "settled" if difference > half else "not settled"
        print(
            f"  {groups[upper]:<26} > {groups[lower]:<26} {difference:+.3f} ± {half:.3f}  "
            f"{np.mean(spread > 0):6.1%}  {verdict}"
        )


if __name__ == "__main__":
    main()
