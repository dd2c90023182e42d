"""Least-cost tolerances of a study for a yield target: `allocate(study_path, yield_target=0.9973)`.

The engineering question: which tolerances should the drawing give so that at
least the target share of the reducers we build meets every spec line of the
study at once (e.g. te_pp and lost_motion), at the lowest total cost
(tolerance/cost.py)?  The search itself, on scales s_i = t_i / t_i,current, is
tolerance/least_cost.py (a surrogate, scipy's optimisers, and the true model's
Monte Carlo having the last word); this module wires the study's reducer
model into it (`_StudyWiring`: scaled studies computed through the study's
own store, so an interrupted allocation loses nothing) and writes the answer:
the allocated study file `<name>_allocated.toml`, ready to run, and
allocation.json.
"""

from __future__ import annotations

import contextlib
import json
import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rvfmu.core.base.checks import InputError, finite_number, integer

from . import cost as costs
from .least_cost import (
    HIGH_YIELD,
    LOOKS,
    MIN_HIGH_YIELD_N,
    Limit,
    Round,
    ScaleAllocation,
    ScaledModel,
    Verified,
    allocate_scales,
    look_confidence,
)
from .surrogate import SURROGATE_KIND

BINDING = 0.005  # a scale within 0.5 % of a bound (the rounding of t) binds it
ROUND_UM = 0.01  # allocated tolerances are written rounded down to 0.01 um


# -- the study: the reducer model wired into the core ---------------------------------------------


@dataclass(frozen=True)
class FactorAllocation:
    """One allocated tolerance: `name` is 'error.key' (e.g. crank_cam_eccentricity.position_um)."""

    name: str
    unit: str
    current: float
    allocated: float
    lower: float
    upper: float
    cost_current: float
    cost_allocated: float
    binding: str  # "none", "lower" (at its tightest) or "upper" (at its loosest)


@dataclass(frozen=True)
class YieldEstimate:
    """A Monte Carlo yield against all spec lines: estimate, Wilson interval, reducers."""

    estimate: float
    low: float
    high: float
    n: int

    @classmethod
    def of(cls, verified: Verified) -> "YieldEstimate":
        """The estimate of a Monte Carlo verification of the least-cost search."""
        return cls(verified.estimate, verified.low, verified.high, verified.n)


@dataclass(frozen=True)
class AllocationResult:
    """The least-cost tolerances of a study for a yield target, and the evidence for them."""

    study: str
    study_file: str
    allocated_study_file: str
    target_yield: float
    feasible: bool
    factors: tuple[FactorAllocation, ...]
    total_cost_current: float
    total_cost_allocated: float
    yield_current: YieldEstimate
    yield_allocated: YieldEstimate
    surrogate_kind: str
    surrogate_samples: int
    surrogate_validation: str
    model_evaluations: int
    spec: tuple[str, ...] = ()
    confidence: float = 0.95
    rounds: tuple[Round, ...] = ()
    files: dict = field(default_factory=dict)
    unconfirmed: bool = False  # verified allocations met the target, fresh draws did not
    looks: tuple[int, ...] = ()  # reducers after which each verification looked (sequential)
    look_confidence: float = 0.95  # the confidence of each look's interval

    def to_json(self) -> dict:
        """The allocation.json document (its schema is read by the HTML report: keep it)."""

        def yield_json(y):
            return {"estimate": y.estimate, "low": y.low, "high": y.high, "n": y.n}

        return {
            "study": self.study,
            "study_file": self.study_file,
            "allocated_study_file": self.allocated_study_file,
            "target_yield": self.target_yield,
            "feasible": self.feasible,
            "factors": [
                {
                    "name": f.name,
                    "unit": f.unit,
                    "current": f.current,
                    "allocated": f.allocated,
                    "lower": f.lower,
                    "upper": f.upper,
                    "cost_current": f.cost_current,
                    "cost_allocated": f.cost_allocated,
                    "binding": f.binding,
                }
                for f in self.factors
            ],
            "total_cost": {"current": self.total_cost_current, "allocated": self.total_cost_allocated},
            "yield": {
                "current": yield_json(self.yield_current),
                "allocated": yield_json(self.yield_allocated),
            },
            "surrogate": {
                "kind": self.surrogate_kind,
                "samples": self.surrogate_samples,
                "validation": self.surrogate_validation,
            },
            "model_evaluations": self.model_evaluations,
        }

    def to_df(self):
        """The allocation as a pandas DataFrame indexed by factor ('error.key', e.g.
        crank_cam_eccentricity.position_um), one row per allocated factor and a last row
        'total' for the reducer as a whole.

        Columns: unit ("um"), current, allocated, lower, upper (the tolerances now and
        allocated and the process bounds, in `unit`), binding ("lower", "upper", "none"),
        cost_current, cost_allocated (per factor; the totals on the 'total' row), and on
        the 'total' row only (NaN elsewhere) the yields against all spec lines at once:
        yield_current, yield_allocated with the low and high ends of their Wilson
        intervals (yield_current_low, ...).  The total row has no tolerances (NaN), unit
        and binding "".
        """
        import pandas as pd

        nan = float("nan")
        rows = [
            {
                "factor": f.name,
                "unit": f.unit,
                "current": f.current,
                "allocated": f.allocated,
                "lower": f.lower,
                "upper": f.upper,
                "binding": f.binding,
                "cost_current": f.cost_current,
                "cost_allocated": f.cost_allocated,
            }
            for f in self.factors
        ]
        total = {
            "factor": "total",
            "unit": "",
            "current": nan,
            "allocated": nan,
            "lower": nan,
            "upper": nan,
            "binding": "",
            "cost_current": self.total_cost_current,
            "cost_allocated": self.total_cost_allocated,
        }
        for label, y in (("current", self.yield_current), ("allocated", self.yield_allocated)):
            total.update(
                {f"yield_{label}": y.estimate, f"yield_{label}_low": y.low, f"yield_{label}_high": y.high}
            )
        frame = pd.DataFrame(rows + [total]).set_index("factor")
        return frame.astype({column: float for column in frame.columns if column not in ("unit", "binding")})

    def table(self) -> str:
        """The printed answer: per factor current vs allocated tolerance and cost; the yields."""
        width = max(len(f.name) for f in self.factors)
        lines = [
            f"allocation of {self.study} for a yield >= {self.target_yield:g} against "
            f"{' and '.join(self.spec)} (all at once)",
            f"{'tolerance [um]':<{width}}  {'current':>8} {'allocated':>9} {'tightest':>8} "
            f"{'loosest':>8}  {'cost now':>9} {'allocated':>9}  binding",
        ]
        for f in self.factors:
            lines.append(
                f"{f.name:<{width}}  {f.current:8.3f} {f.allocated:9.3f} {f.lower:8.3f} "
                f"{f.upper:8.3f}  {f.cost_current:9.4g} {f.cost_allocated:9.4g}  "
                f"{'-' if f.binding == 'none' else f.binding}"
            )
        lines.append(
            f"{'total cost':<{width}}  {'':37}  {self.total_cost_current:9.4g} "
            f"{self.total_cost_allocated:9.4g}"
        )
        c = f"{100 * self.confidence:g} %"
        for label, y in (("current", self.yield_current), ("allocated", self.yield_allocated)):
            lines.append(
                f"yield, {label:<9} {y.estimate:.5f}  ({c} interval {y.low:.5f} - "
                f"{y.high:.5f}, Monte Carlo of {y.n} reducers of the true model)"
            )
        if len(self.looks) > 1:
            lines.append(
                f"verification: sequential, a look after {', '.join(map(str, self.looks))} "
                f"reducers, stopped at the first clear of the target; each look's interval at "
                f"{100 * self.look_confidence:.3g} % so that the {c} holds over all {len(self.looks)}"
            )
        if self.unconfirmed:
            lines.append(
                f"target {self.target_yield:g}: NOT CONFIRMED: the cheapest allocations "
                "that met it in the search fell short on fresh draws (the yield above); "
                "give a larger -n"
            )
        elif self.feasible:
            lines.append(
                f"target {self.target_yield:g}: met (the low end of the verification's "
                f"{c} interval is at or above it)"
            )
        else:
            bound = [
                f"{f.name} ({'tightest' if f.binding == 'lower' else 'loosest'})"
                for f in self.factors
                if f.binding != "none"
            ]
            lines.append(
                f"target {self.target_yield:g}: OUT OF REACH within the bounds; the best "
                "yield found is the one above, at the tolerances above; bounds that "
                f"bind: {', '.join(bound) or 'none'}"
            )
        lines.append(
            f"surrogate: {self.surrogate_kind}, {self.surrogate_samples} reducers; "
            f"{self.surrogate_validation}"
        )
        lines.append(
            f"model evaluations: {self.model_evaluations} in {len(self.rounds)} "
            "verification rounds plus training and the current tolerances"
        )
        return "\n".join(lines)


def allocate(
    study_path,
    yield_target: float = 0.9973,
    output=None,
    progress: bool | None = None,
    *,
    n: int | None = None,
    processes: int | None = None,
    log=None,
    yes: bool = False,
    looks: int | None = None,
) -> AllocationResult:
    """The least-cost tolerances of a study file with a verified yield >= yield_target.

    The yield is that of all spec lines at once; costs and bounds come from the
    [tolerances.NAME.cost] tables (tolerance/cost.py).  n: reducers of each
    verification Monte Carlo at most (default the study's [montecarlo] n, at least
    MIN_HIGH_YIELD_N for a target >= HIGH_YIELD); looks: each verification looks
    at its yield up to this many times and stops once its interval is clear of
    the target (tolerance/least_cost.py, step 6; 1: one Monte Carlo of n
    reducers; default LOOKS); processes: local worker processes for the training groups and
    those Monte Carlo runs.  Everything is
    stored in the output folder (default the study's; it must be this study's
    or new): the current
    tolerances' Monte Carlo as `rvte mc` would store it, the training and the
    verifications under allocation/, and `<study name>_allocated.toml` (ready
    to run, with the seed of its confirmation: its `rvte mc` reuses that) and allocation.json.
    log(str) gets the progress of the search; `yes` as for `run_mc`.
    """
    from .run import _load, _warn_load
    from .store import open_output
    from .study import flag

    progress, yes = flag("progress", progress, none=True), flag("yes", yes)
    study = _load(study_path, output)
    target = finite_number("yield", yield_target)
    if not 0.0 < target < 1.0:
        raise InputError("yield", target, "must be between 0 and 1 (e.g. 0.9973)")
    if not study.spec:
        raise InputError(
            "spec", None, "an allocation needs at least one spec line: give the study a [spec] table"
        )
    if n is None:
        n = max(study.mc_n, MIN_HIGH_YIELD_N) if target >= HIGH_YIELD else study.mc_n
    n = integer("n", n, 1)
    looks = LOOKS if looks is None else integer("looks", looks, 1, 16)
    folder = open_output(study, study.output)
    allocated_path = folder / f"{_file_name(study.name)}_allocated.toml"
    if study.path is not None and allocated_path.resolve() == Path(study.path).resolve():
        raise InputError(
            "output",
            str(folder),
            f"would overwrite the study file {study.path} with its allocation: choose another output folder",
        )
    _warn_load(study, log)
    wiring = _StudyWiring(study, _allocated_factors(study), folder, progress, log, yes, processes)
    with wiring.kept_backend():
        result = allocate_scales(
            wiring.model(),
            target,
            n,
            log=log,
            progress=progress,
            column_names=study.metric_columns,
            looks=looks,
        )
    # the reducers of the look that decided the current tolerances (their n counts the
    # finite ones only)
    wiring.current_files(next((size for size in result.looks if size >= result.current.n), n))
    return wiring.report(result, target, allocated_path)


def study_model(study_path, output=None, processes: int | None = None, log=None) -> ScaledModel:
    """The study's reducer model as the search sees it: a ScaledModel over its nonzero tolerances.

    For other searches over the same problem (studies/benchmarks/bench_allocate.py
    runs a plain Monte-Carlo-in-the-loop optimiser on it); `allocate` builds the same.
    """
    from .run import _load
    from .store import open_output

    study = _load(study_path, output)
    factors = _allocated_factors(study)
    return _StudyWiring(study, factors, open_output(study, study.output), False, log, True, processes).model()


def _allocated_factors(study) -> list:
    """The factors an allocation changes: every nonzero tolerance (an exact source stays exact)."""
    factors = [f for f in study.factors if costs.current_um(f) > 0]
    if not factors:
        raise InputError("tolerances", None, "every tolerance is zero: nothing to allocate")
    return factors


class _StudyWiring:
    """The study's reducer model as a ScaledModel: scaled studies, computed through the store."""

    def __init__(self, study, factors, folder: Path, progress, log, yes, processes):
        self.study, self.factors, self.folder = study, factors, folder
        self.progress, self.log, self.yes, self.processes = progress, log, yes, processes
        self.models = tuple(costs.resolved(f) for f in factors)
        self.current = np.array([costs.current_um(f) for f in factors])
        self.layout = [(f, start, stop) for f, start, stop in study.layout if f in factors]
        self.backend = None  # the verifications' backend while `kept_backend` holds it open

    @contextlib.contextmanager
    def kept_backend(self):
        """One backend for every verification Monte Carlo of the search: a pool of worker
        processes starts once, not at each look of each verification.  An error or Ctrl-C
        ends its workers at once, as a run's own backend does."""
        from .backends import make_backend

        backend = make_backend(self.processes)
        with backend:
            self.backend = _Entered(backend)
            try:
                yield
            finally:
                self.backend = None

    def model(self) -> ScaledModel:
        study = self.study
        limits = tuple(
            Limit(study.metric_columns.index(limit.column), limit.limit, limit.sense) for limit in study.spec
        )
        return ScaledModel(
            names=tuple(f"{f.name}.{costs.ALLOCATED[f.kind]}" for f in self.factors),
            current=self.current,
            costs=self.models,
            limits=limits,
            columns=len(study.columns),
            magnitudes=self.magnitudes,
            evaluate=self.evaluate,
            verify=self.verify,
            log_inputs=True,
            snap=self.snap,
            seed=study.seed,
            confidence=study.mc_confidence,
            evaluate_groups=self.evaluate_groups,
            block=study.batch_size,
        )

    def magnitudes(self, U: np.ndarray) -> np.ndarray:
        """RMS of each allocated factor's error values [um] at the current tolerances: (n, F)."""
        from rvfmu.core.base.units import UM

        from .sampling import factor_values

        out = np.empty((U.shape[0], len(self.layout)))
        for j, (factor, start, stop) in enumerate(self.layout):
            values = np.abs(factor_values(factor, self.study.design, U[:, start:stop])) / UM
            out[:, j] = np.sqrt(np.mean(values.reshape(U.shape[0], -1) ** 2, axis=1))
        return out

    def snap(self, scales: np.ndarray) -> np.ndarray:
        """Tolerances rounded down to ROUND_UM (never looser than asked), within the bounds."""
        t = np.floor(scales * self.current / ROUND_UM + 1e-9) * ROUND_UM
        low = np.array([m.tightest_um for m in self.models])
        high = np.array([m.loosest_um for m in self.models])
        return np.clip(t, low, high) / self.current

    def scaled_factors(self, scales, with_cost: bool) -> tuple:
        """The study's factors with the allocated ones at scales (their resolved costs, or none).

        The allocated tolerance is kept within its bounds to the last bit and
        written to 1e-9 um; the keys that follow it to 1e-4 um.
        """
        scaled = dict(zip((f.name for f in self.factors), zip(scales, self.models, self.current)))
        out = []
        for f in self.study.factors:
            if f.name in scaled:
                s, model, t0 = scaled[f.name]
                t = min(max(round(float(s) * t0, 9), model.tightest_um), model.loosest_um)
                values = {key: round(value, 4) for key, value in costs.scaled_values(f, t / t0).items()}
                values[costs.ALLOCATED[f.kind]] = t
                f = replace(f, **values, cost=model if with_cost else None)
            out.append(f)
        return tuple(out)

    def scaled_study(self, scales, rows: int):
        """The study at these scales, one batch of `rows`, stored under allocation/<hash>."""
        study = replace(self.study, factors=self.scaled_factors(scales, False), batch_size=rows, text="")
        return replace(study, output=self.folder / "allocation" / study.inputs_hash[:12])

    def evaluate(self, scales, U, job) -> np.ndarray:
        """Metrics of training reducers U at scales, stored in their scaled study's folder."""
        return _train_group(self.scaled_study(scales, U.shape[0]), U, job)

    def evaluate_groups(self, tasks):
        """The training groups (scales, U, job), in order; on worker processes if asked: those
        of the verifications' backend while `kept_backend` holds it open, else a pool of their
        own."""
        studies = [(self.scaled_study(s, U.shape[0]), U, job) for s, U, job in tasks]
        if not self.processes or self.processes < 2:
            yield from (_train_group(*task) for task in studies)
            return
        from concurrent.futures.process import BrokenProcessPool

        from .backends import _DIED, Processes, local_pool, spawning, stop_pool

        kept = getattr(self.backend, "backend", None)
        if isinstance(kept, Processes):
            yield from kept.calls(_train_group, studies, chunksize=4)
            return

        pool = local_pool(self.processes)  # as the Processes backend's
        finished = False
        try:
            with spawning():  # workers start at the first tasks, all sent here
                results = pool.map(_train_group, *zip(*studies), chunksize=4)
            yield from results
            finished = True
        except BrokenProcessPool as exc:
            raise RuntimeError(_DIED.format(exc=exc)) from None
        finally:
            stop_pool(pool, abort=not finished)  # Ctrl-C or an error: end the workers at once

    def verify(self, scales, n: int, draw: int = 0):
        """The Monte Carlo of n reducers of the study file with these tolerances, on draws
        number `draw`: rows 0 to n - 1 of that file's `rvte mc`, its seed `seed_of(draw)`,
        computed in whole batches as `rvte mc -n n` computes them (so a larger n, and that
        command, reuse every one).

        Draws 0 at the current tolerances are the study's own `rvte mc`, in its own
        output folder (`current_files` writes its files once the search is over).
        """
        from . import montecarlo
        from .backends import make_backend
        from .run import compute

        if draw == 0 and np.all(scales == 1.0):
            study = self.study
            output = self.folder
        else:
            study = self.candidate(scales, draw=draw)[1]
            output = study.output
        computed = compute(
            study,
            "mc",
            math.ceil(n / study.batch_size) * study.batch_size,
            lambda a, b: montecarlo.rows(study, a, b),
            self.backend or make_backend(self.processes),
            self.progress,
            self.log,
            output=output,
            yes=self.yes,
            size_field=("n", n),
        )
        return computed.Y[:n]

    def current_files(self, n: int) -> None:
        """`rvte mc` of the study itself at the n reducers its verification ran (every batch
        stored: summary, samples and worst reducer written, no figures), so that the output
        folder is ready for `rvte report`."""
        from .mc_runs import run_mc

        run_mc(
            self.study,
            n,
            output=self.folder,
            processes=self.processes,
            progress=self.progress,
            plots=False,
            log=self.log,
            yes=self.yes,
        )

    def seed_of(self, draw: int) -> int:
        """The seed of draws number `draw`: the study's for 0, else one derived from it."""
        if draw == 0:
            return self.study.seed
        return int(
            np.random.SeedSequence([self.study.seed, 0x616C6C6F, draw]).generate_state(2, np.uint64)[0] >> 1
        )

    def candidate(self, scales, header: str = "", draw: int = 0):
        """(text, Study) of the study file with the allocated tolerances at scales, and the
        seed of draws number `draw`.

        The file is written beside allocation.json; its output folder is the
        verification's (allocation/<inputs hash>), so its `rvte mc` reuses it.
        """
        from .study import study_from_values

        path = self.folder / f"{_file_name(self.study.name)}_allocated.toml"
        factors = self.scaled_factors(scales, True)
        seeded = replace(self.study, seed=self.seed_of(draw))
        probe = replace(seeded, factors=factors)
        same = probe.inputs_hash == self.study.inputs_hash
        text = allocated_text(
            seeded, factors, "." if same else f"allocation/{probe.inputs_hash[:12]}", header
        )
        study = study_from_values(tomllib.loads(text), path, text)
        assert study.inputs_hash == probe.inputs_hash, "the allocated file must be what was verified"
        return text, study

    def report(self, result: ScaleAllocation, target: float, path: Path) -> AllocationResult:
        """Write the allocated study file and allocation.json; the result record."""
        study = self.study
        sizes = result.looks
        level = look_confidence(study.mc_confidence, max(len(sizes), 1))
        factors = []
        for f, model, t0, s, lo, hi in zip(
            self.factors,
            self.models,
            self.current,
            result.scales,
            np.log(self.model().lower),
            np.log(self.model().upper),
        ):
            t = float(s * t0)
            binding = (
                "lower"
                if abs(math.log(s) - lo) <= BINDING
                else "upper"
                if abs(math.log(s) - hi) <= BINDING
                else "none"
            )
            factors.append(
                FactorAllocation(
                    f"{f.name}.{costs.ALLOCATED[f.kind]}",
                    "um",
                    float(t0),
                    round(t, 6),
                    float(model.tightest_um),
                    float(model.loosest_um),
                    float(model.cost(t0)),
                    float(model.cost(t)),
                    binding,
                )
            )
        current, allocated = result.current, result.allocated
        header = (
            f"Allocated by `rvte allocate` from {study.path or study.name} for a yield >= "
            f"{target:g} against {', '.join(str(limit) for limit in study.spec)} (all at once).\n"
            + (
                f"Verified: yield {allocated.estimate:.5f} ({100 * study.mc_confidence:g} % "
                f"interval {allocated.low:.5f} - {allocated.high:.5f}) of {allocated.n} "
                "reducers"
                if result.feasible
                else f"OUT OF REACH within the bounds: the best yield found, {allocated.estimate:.5f} "
                f"({allocated.low:.5f} - {allocated.high:.5f}) of {allocated.n} reducers, with "
                "these tolerances"
            )
            + f"; total cost {sum(f.cost_allocated for f in factors):.4g} (was "
            f"{sum(f.cost_current for f in factors):.4g}).\n"
            + (
                "The yield is that of this file's Monte Carlo (its seed), reducers that no "
                "step of the search saw.\n"
                if result.confirmations
                else ""
            )
            + (
                f"The interval is at {100 * level:.3g} %, so that the {100 * study.mc_confidence:g} % "
                f"holds over the sequential verification's {len(sizes)} looks ({', '.join(map(str, sizes))} "
                "reducers); `rvte mc` prints the plain one.\n"
                if len(sizes) > 1
                else ""
            )
            + f"Run: rvte mc {path.name} -n {allocated.n}   (reuses that Monte Carlo)"
        )
        text, _ = self.candidate(result.scales, header, allocated.draw)
        path.write_text(text)
        record = AllocationResult(
            study=study.name,
            study_file=str(study.path or ""),
            allocated_study_file=str(path),
            target_yield=target,
            feasible=result.feasible,
            factors=tuple(factors),
            total_cost_current=float(sum(f.cost_current for f in factors)),
            total_cost_allocated=float(sum(f.cost_allocated for f in factors)),
            yield_current=YieldEstimate.of(current),
            yield_allocated=YieldEstimate.of(allocated),
            surrogate_kind=SURROGATE_KIND,
            surrogate_samples=result.samples,
            surrogate_validation=result.validation,
            model_evaluations=result.evaluations,
            spec=tuple(str(limit) for limit in study.spec),
            confidence=study.mc_confidence,
            rounds=result.rounds,
            unconfirmed=not result.feasible and bool(result.confirmations),
            looks=tuple(sizes),
            look_confidence=level,
            files={"allocated_study": path, "allocation": self.folder / "allocation.json"},
        )
        (self.folder / "allocation.json").write_text(json.dumps(record.to_json(), indent=1) + "\n")
        return record


class _Entered:
    """A backend already entered, lent to runs that enter and leave it: they leave it open."""

    def __init__(self, backend):
        self.backend, self.workers = backend, backend.workers

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def describe(self) -> str:
        return self.backend.describe()

    def map(self, study, tasks):
        return self.backend.map(study, tasks)


def _train_group(study, U, job) -> np.ndarray:
    """Metrics of one training group (its own Study, one batch) through the store."""
    from .backends import make_backend
    from .run import compute

    computed = compute(
        study,
        job,
        U.shape[0],
        lambda a, b: U[a:b],
        make_backend(),
        progress=False,
        output=study.output,
        yes=True,
    )
    return np.where(np.isfinite(computed.Y), computed.Y, np.nan)


def allocated_text(study, factors, output: str, header: str = "") -> str:
    """The study file of `study` with `factors`, every value explicit, paths absolute.

    Relative paths of the original are resolved (the file is written
    elsewhere); `output` is written as given (relative to the new file).
    Loading it gives the same inputs hash as replace(study, factors=factors).
    """
    errors = ""
    if study.errors_source:
        errors = Path(study.errors_source)
        if not errors.is_absolute() and study.path is not None:
            errors = Path(study.path).resolve().parent / errors
    tables = {
        "study": {
            "name": f"{study.name}_allocated",
            "design": study.design_source or study.design.name,
            "errors": str(errors) if errors else None,
            "seed": study.seed,
            "metrics": list(study.metrics),
            "batch_size": study.batch_size,
            "output": output,
        },
        "operating": {
            "load_Nm": study.load_Nm,
            "points": study.points,
            "windup_positions": study.windup_positions,
        },
        "spec": {limit.column: limit.limit for limit in study.spec},
        "montecarlo": {"n": study.mc_n, "confidence": study.mc_confidence},
        "sobol": {
            "n": study.sobol_n,
            "second_order": study.second_order,
            "resamples": study.resamples,
            "confidence": study.sobol_confidence,
        },
    }
    for f in factors:
        tables[f"tolerances.{f.name}"] = f.file_values()
        if f.cost is not None:
            tables[f"tolerances.{f.name}.cost"] = costs.file_values(f.cost)
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    for name, values in tables.items():
        lines += ["" if lines else None, f"[{name}]"]
        lines += [f"{key} = {_toml_value(value)}" for key, value in values.items() if value is not None]
    return "\n".join(line for line in lines if line is not None) + "\n"


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, float):
        return repr(float(value))  # round-trips exactly (also a numpy float)
    return str(value)


def _file_name(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name)


__all__ = [
    "allocate",
    "AllocationResult",
    "FactorAllocation",
    "YieldEstimate",
    "allocated_text",
    "study_model",
]
