"""The surrogate of the allocation search: P(a reducer passes every spec line | its error sizes).

A sparse polynomial chaos (OpenTURNS FunctionalChaosAlgorithm, Legendre basis
of total degree DEGREE, LARS with corrected leave-one-out) gives the mean of
each spec metric (its log, when it is positive), and a second one the log of
the squared residual (heteroscedastic noise: the spread of TE at given error
sizes grows with them).  Polynomial chaos rather than Kriging: the training
holds thousands to tens of thousands of reducers whose metric is a noisy
function of its inputs (phases and tooth patterns are not inputs); LARS fits
that in seconds and its cost grows linearly with the samples, where Kriging's
grows with their cube and would interpolate the noise.  OpenTURNS fits the
chaos; numpy evaluates it (the optimiser calls it millions of times).
"""

from __future__ import annotations

import numpy as np
from scipy.special import log_ndtr, ndtr

DEGREE = 2  # total degree of the chaos; 3 fitted no better on the RV-40E studies
SIGMA_FLOOR = 0.02  # residual sigma >= this x the metric's spread: keeps the yield smooth
SURROGATE_KIND = (
    "polynomial chaos (OpenTURNS FunctionalChaosAlgorithm, Legendre degree "
    f"{DEGREE}, LARS, corrected leave-one-out) of each spec metric and of its "
    "residual variance"
)


# -- the surrogate ------------------------------------------------------------------------------


class Chaos:
    """A sparse polynomial chaos on inputs in [-1, 1]^d: fitted by OpenTURNS, evaluated by numpy.

    Orthonormal Legendre polynomials (the basis of the uniform measure on
    [-1, 1]), total degree `degree`, terms chosen by LARS with the corrected
    leave-one-out error.  `metamodel` is OpenTURNS's own evaluation (for checks);
    `loo_error` the corrected leave-one-out error of the kept terms relative to the
    variance of y (Blatman & Sudret 2011, J. Comput. Phys. 230), so that Q2 = 1 - loo_error.
    """

    def __init__(self, X: np.ndarray, y: np.ndarray, degree: int = DEGREE):
        import openturns as ot

        d = X.shape[1]
        basis = ot.OrthogonalProductPolynomialFactory([ot.LegendreFactory()] * d)
        enumerate_ = basis.getEnumerateFunction()
        algo = ot.FunctionalChaosAlgorithm(
            ot.Sample(np.ascontiguousarray(X)),
            ot.Sample(np.ascontiguousarray(y)[:, None]),
            ot.JointDistribution([ot.Uniform(-1.0, 1.0)] * d),
            ot.FixedStrategy(basis, enumerate_.getBasisSizeFromTotalDegree(degree)),
            ot.LeastSquaresStrategy(
                ot.LeastSquaresMetaModelSelectionFactory(ot.LARS(), ot.CorrectedLeaveOneOut())
            ),
        )
        algo.run()
        result = algo.getResult()
        self.degree = degree
        self.alpha = np.array([list(enumerate_(int(i))) for i in result.getIndices()], dtype=int)
        self.coefficients = np.asarray(result.getCoefficients())[:, 0]
        self.metamodel = result.getMetaModel()
        # LARS keeps the step of least error: the kept basis is the minimum of the history
        self.loo_error = float(min(result.getErrorHistory()))
        self.quadratic = _quadratic_form(self.alpha, self.coefficients) if degree <= 2 else None

    def __call__(self, X: np.ndarray) -> np.ndarray:
        """Values at X (n, d) in [-1, 1]: (n,); of degree 2 or less as the quadratic form
        `quadratic` (two BLAS products), else by `terms`."""
        if self.quadratic is None:
            return self.terms(X)
        k0, g, Q = self.quadratic
        return k0 + X @ g + np.einsum("nd,nd->n", X @ Q, X)

    def value_gradient(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values (n,) and gradient (n, d) with respect to X at X (n, d) in [-1, 1]: of
        degree 2 or less by the quadratic form (the gradient g + 2 Q x), else by
        `terms_value_gradient`."""
        if self.quadratic is None:
            return self.terms_value_gradient(X)
        k0, g, Q = self.quadratic
        XQ = X @ Q
        return k0 + X @ g + np.einsum("nd,nd->n", XQ, X), g + 2.0 * XQ

    def terms(self, X: np.ndarray) -> np.ndarray:
        """Values at X (n, d) summed term by term over the orthonormal Legendre products (any
        degree; the reference of the quadratic form)."""
        P, _ = self._legendre(X, derivatives=False)
        out = np.zeros(P.shape[2])
        for alpha, c in zip(self.alpha, self.coefficients):
            nonzero = np.flatnonzero(alpha)
            if nonzero.size == 0:
                out += c
                continue
            term = c * P[alpha[nonzero[0]], nonzero[0]]
            for i in nonzero[1:]:
                term *= P[alpha[i], i]
            out += term
        return out

    def terms_value_gradient(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`value_gradient` term by term (any degree; the reference of the quadratic form)."""
        P, D = self._legendre(X, derivatives=True)
        value, gradient = np.zeros(P.shape[2]), np.zeros(P.shape[1:])  # (n,), (d, n)
        for alpha, c in zip(self.alpha, self.coefficients):
            nonzero = np.flatnonzero(alpha)
            if nonzero.size == 0:
                value += c
                continue
            factors = [P[alpha[i], i] for i in nonzero]
            value += c * np.prod(factors, axis=0)
            for j, i in enumerate(nonzero):  # product rule: one factor differentiated
                others = factors[:j] + factors[j + 1 :]
                gradient[i] += c * D[alpha[i], i] * (np.prod(others, axis=0) if others else 1.0)
        return value, gradient.T

    def _legendre(self, X, derivatives: bool):
        """Orthonormal Legendre values P (degree + 1, d, n) at X (n, d), and their derivatives."""
        X = np.ascontiguousarray(X.T)  # (d, n): each polynomial row contiguous
        P = np.empty((self.degree + 1,) + X.shape)
        D = np.zeros_like(P) if derivatives else None
        P[0] = 1.0
        if self.degree:
            P[1] = X
            if derivatives:
                D[1] = 1.0
        for n in range(1, self.degree):  # Bonnet's recursion
            P[n + 1] = ((2 * n + 1) * X * P[n] - n * P[n - 1]) / (n + 1)
            if derivatives:  # P'_{n+1} = P'_{n-1} + (2n + 1) P_n
                D[n + 1] = D[n - 1] + (2 * n + 1) * P[n]
        norm = np.sqrt(2.0 * np.arange(self.degree + 1) + 1.0)[:, None, None]
        P *= norm
        if derivatives:
            D *= norm
        return P, D


def _quadratic_form(alpha: np.ndarray, coefficients: np.ndarray) -> tuple:
    """(k0, g (d,), Q (d, d) symmetric) with chaos(x) = k0 + g . x + x . Q x, for a chaos of
    total degree 2 or less (multi-indices alpha (terms, d), coefficients (terms,)).

    With the orthonormal Legendre polynomials P1(x) = sqrt(3) x and P2(x) = sqrt(5) (3 x^2 -
    1) / 2, a term c P1(x_i) adds sqrt(3) c to g_i, c P2(x_i) adds 3 sqrt(5) c / 2 to Q_ii
    and -sqrt(5) c / 2 to k0, and c P1(x_i) P1(x_j) adds 3 c / 2 to Q_ij and to Q_ji.
    """
    d = alpha.shape[1]
    k0, g, Q = 0.0, np.zeros(d), np.zeros((d, d))
    root3, root5 = np.sqrt(3.0), np.sqrt(5.0)
    for a, c in zip(alpha, coefficients):
        nonzero = np.flatnonzero(a)
        if nonzero.size == 0:
            k0 += c
        elif nonzero.size == 1 and a[nonzero[0]] == 1:
            g[nonzero[0]] += root3 * c
        elif nonzero.size == 1:  # a[i] == 2
            i = nonzero[0]
            Q[i, i] += 1.5 * root5 * c
            k0 -= 0.5 * root5 * c
        else:  # x_i x_j
            i, j = nonzero
            Q[i, j] += 1.5 * c
            Q[j, i] += 1.5 * c
    return k0, g, Q


class Surrogate:
    """P(a reducer passes every limit | its inputs Z), from the training inputs Z (n, F) and Y (n, M).

    Per metric column: g = log(value) if every value and limit is positive,
    else the value; g = mean(Z) + sigma(Z) * e, mean and log sigma^2 each a
    `Chaos`; e standard normal.  Lines are treated as independent given Z.
    """

    def __init__(self, Z: np.ndarray, Y: np.ndarray, limits: tuple, degree: int = DEGREE):
        self.limits = limits
        self.low, self.high = Z.min(axis=0), Z.max(axis=0)
        self.high = np.where(self.high > self.low, self.high, self.low + 1.0)
        X = self.unit(Z)
        self.fits = {}
        for column in sorted({limit.column for limit in limits}):
            y = Y[:, column]
            log = bool(np.all(y > 0) and all(limit.limit > 0 for limit in limits if limit.column == column))
            g = np.log(y) if log else y
            spread = float(g.std()) or 1.0
            mean = Chaos(X, g, degree)
            residual = g - mean(X)
            tiny = (1e-3 * spread) ** 2
            log_variance = Chaos(X, np.log(residual**2 + tiny), degree)
            # in-sample residuals understate the spread by the terms fitted; E[log chi2_1] = -1.2704
            inflate = X.shape[0] / max(1, X.shape[0] - mean.coefficients.size)
            fitted = log_variance(X)
            self.fits[column] = (
                log,
                mean,
                log_variance,
                inflate,
                SIGMA_FLOOR * spread,
                (fitted.min(), fitted.max()),
            )

    def unit(self, Z: np.ndarray) -> np.ndarray:
        """Inputs mapped onto [-1, 1] over the training range (clipped: no extrapolation)."""
        return np.clip(2.0 * (Z - self.low) / (self.high - self.low) - 1.0, -1.0, 1.0)

    def transform(self, column: int, values):
        """`values` of metric `column` on the scale the fit uses: log where every value and
        limit was positive, else as they are (float array, same shape)."""
        log = self.fits[column][0]
        return np.log(values) if log else np.asarray(values, dtype=float)

    def mean_sigma(self, column: int, X: np.ndarray):
        """mean (n,) and sigma (n,) of metric `column` on its fitted scale at the unit inputs
        X (n, F) (`unit`); sigma never below its floor."""
        log, mean, log_variance, inflate, floor, (lo, hi) = self.fits[column]
        variance = np.exp(np.clip(log_variance(X), lo, hi) + 1.2704) * inflate
        return mean(X), np.maximum(np.sqrt(variance), floor)

    def mean_sigma_gradient(self, column: int, X: np.ndarray):
        """mean (n,), sigma (n,) and their gradients (n, F) with respect to X."""
        log, mean, log_variance, inflate, floor, (lo, hi) = self.fits[column]
        mu, d_mu = mean.value_gradient(X)
        lv, d_lv = log_variance.value_gradient(X)
        sigma = np.sqrt(np.exp(np.clip(lv, lo, hi) + 1.2704) * inflate)
        free = (lv > lo) & (lv < hi) & (sigma > floor)  # where neither clip nor floor binds
        d_sigma = np.where(free, 0.5 * sigma, 0.0)[:, None] * d_lv
        return mu, np.maximum(sigma, floor), d_mu, d_sigma

    def probability(self, Z: np.ndarray, gradient: bool = False):
        """P(pass every limit) of each input row (n,); with `gradient`, also its gradient
        with respect to Z (n, F) (zero along an input clipped to the training range)."""
        X = self.unit(Z)
        p = np.ones(Z.shape[0])
        d_log_p = np.zeros(Z.shape) if gradient else None  # d ln p / dX
        cache = {}
        for limit in self.limits:
            if limit.column not in cache:
                cache[limit.column] = (
                    self.mean_sigma_gradient(limit.column, X)
                    if gradient
                    else self.mean_sigma(limit.column, X)
                )
            mu, sigma = cache[limit.column][:2]
            bound = self.transform(limit.column, limit.limit)
            sign = 1.0 if limit.sense == "max" else -1.0
            a = sign * (bound - mu) / sigma
            p_line = ndtr(a)
            p *= p_line
            if gradient:
                d_mu, d_sigma = cache[limit.column][2:]
                d_a = (-sign * d_mu - a[:, None] * d_sigma) / sigma[:, None]
                # d ln Phi(a) = phi(a) / Phi(a) da, written stably (Mills ratio) far in the tail
                ratio = np.exp(-0.5 * a * a - log_ndtr(a)) / np.sqrt(2.0 * np.pi)
                d_log_p += ratio[:, None] * d_a
        if not gradient:
            return p
        inside = (Z > self.low) & (Z < self.high)
        return p, p[:, None] * d_log_p * np.where(inside, 2.0 / (self.high - self.low), 0.0)

    def check(self, Z: np.ndarray, Y: np.ndarray) -> str:
        """Held-out quality: per column Q2 of the mean and mean/sd of the standardised residual."""
        X = self.unit(Z)
        parts = []
        for column in self.fits:
            g = self.transform(column, Y[:, column])
            mu, sigma = self.mean_sigma(column, X)
            q2 = 1.0 - np.mean((g - mu) ** 2) / max(np.var(g), 1e-300)
            e = (g - mu) / sigma
            parts.append(
                f"column {column}: Q2 {q2:.3f}, standardised residual mean {e.mean():+.2f} sd {e.std():.2f}"
            )
        return "; ".join(parts)
