"""What `rvte report` shows: a study's output folder read, checked and laid out as sections.

The question a report answers for someone who was not there: what was
computed, from exactly which inputs, and is it still what the study file and
the model say?  So the report reads the output folder as `rvte mc` and
`rvte sobol` left it (manifest.json, inputs.json, study.toml, mc_summary.json,
mc_samples.csv, sobol_indices.json, the batch files' names, and allocation.json
if a tolerance allocation wrote one) and puts at its top whether the study file
or the model changed since (`Freshness`): the inputs hash of the study file as
it is now and the fingerprint of the model as it is now, against those the
store recorded.  The study it describes is the one that computed the store
(`stored_study`): its identity from inputs.json, which hashes to the
manifest's inputs hash, the rest from the folder's copy of the study file.

The only model run is the nominal reducer (every tolerance zero, the study's
fixed errors if it has some) at the study's operating point.  Every other
number is read from the JSON outputs and shown rounded; a table cell holding
one names its source (`data-src` file, `data-key` JSON path, and `data-scale`
if it shows the value times a factor, e.g. 100 for a percentage), so a script
can check the HTML against the JSON.  The figures are the `figure_*` builders of
tolerance/summaries.py and rvfmu/plots.py, as PNG bytes.

This module gathers the content once (`gather` -> `Content`: sections of
paragraphs, tables of text and `Num` cells, code and figures); how it looks in
HTML and Markdown is tolerance/html_report.py's and its templates' business.
"""

from __future__ import annotations

import hashlib
import io
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rvfmu.api import read_columns
from rvfmu.core.base.checks import InputError
from rvfmu.core.reducer.errors import error_file_values, load_errors, toml_text
from rvfmu.core.statics import metrics
from rvfmu.core.statics.quasistatic import default_points, te_curve
from rvfmu.plots import figure_te

from .aliasing import aliases
from .evaluate import FRICTION_METRICS, WINDUP_METRICS, evaluate
from .montecarlo import PERCENTILES, MCAnalysis, Yield
from .sampling import KEYS
from .sobol import Convergence, Indices, SobolAnalysis
from .store import FILE_DIGEST, software_versions
from .study import Study, load_study, model_fingerprint, study_from_store
from .summaries import (
    NOTES_LEGEND,
    column_label,
    figure_convergence,
    figure_mc,
    figure_sobol,
    operating_text,
    order_text,
)

# The keys of the JSON outputs the report reads (tolerance/summaries.py writes them).
MC_KEYS = (
    "n",
    "evaluated",
    "failed",
    "not_converged",
    "metrics",
    "yields",
    "worst",
    "computed_rows",
    "batch_size",
    "operating",
)
SOBOL_KEYS = ("n", "second_order", "evaluations", "resamples", "confidence", "factors", "metrics")
# 100 dpi: the builders' 9-10 inch figures come out about 1000 px wide, the report's column
# at laptop width (1366 px), so the browser shows them at about their own size.
FIGURE_DPI = 100
ORDERS_SHOWN = 5  # largest orders of the nominal TE listed in its table
S2_SHOWN = 5  # largest second-order indices listed per metric


# -- the content, once, for both renderers -------------------------------------------------


@dataclass(frozen=True)
class Num:
    """A number in a table: `value` (None: not finite) times `scale`, shown with `fmt`.

    src, key: the JSON file and the path in it (a list of keys and indices) it was read from.
    """

    value: float | None
    fmt: str = ".4g"
    scale: float = 1.0
    src: str = ""
    key: tuple = ()

    def text(self) -> str:
        """The number as the report shows it: value times scale in `fmt` ("d": an integer,
        the value unscaled), "n/a" if it is None or not finite."""
        if self.value is None or not np.isfinite(self.value):
            return "n/a"
        if self.fmt == "d":
            return str(int(self.value))
        return format(self.value * self.scale, self.fmt)


@dataclass(frozen=True)
class Table:
    """head: column titles; rows, foot: tuples of cells (text or Num); columns: HTML shows the
    rows side by side in that many tables (a long list of short rows)."""

    head: tuple
    rows: list
    caption: str = ""
    foot: list = field(default_factory=list)
    columns: int = 1


@dataclass(frozen=True)
class Figure:
    """A figure: its PNG bytes (at FIGURE_DPI) and caption; HTML only, Markdown leaves it out."""

    png: bytes
    caption: str


@dataclass(frozen=True)
class Code:
    """A file's text shown verbatim under a title (a study file, an error file), as a code
    block in `language`."""

    title: str
    text: str
    language: str = "toml"


@dataclass(frozen=True)
class Para:
    """A paragraph of text; level: "" plain, "note" a note, "h3" a heading, "bad", "warn" or
    "ok" a box."""

    text: str
    level: str = ""  # "", "note", "h3" (a heading); boxes: "bad", "warn", "ok"


@dataclass(frozen=True)
class Section:
    """A section of the report: `id` its HTML anchor (the contents bar links it), `title` its
    heading, `blocks` its Para, Table, Code and Figure blocks in order."""

    id: str
    title: str
    blocks: list


def _json_num(data: dict, src: str, *key, fmt=".4g", scale=1.0) -> Num:
    value = data
    for k in key:
        value = value[k]
    return Num(None if value is None else float(value), fmt, scale, src, key)


# -- reading the folder ----------------------------------------------------------------------


@dataclass(frozen=True)
class Found:
    """The output folder's files as read: JSON as dicts, texts as str, None where absent."""

    manifest: dict
    inputs: dict
    study_text: str
    mc: dict | None
    samples: np.ndarray | None  # (n, M) metric columns of mc_samples.csv
    sobol: dict | None
    allocation: dict | None
    worst_errors: str | None
    digests: dict  # {file name: sha256} of every file read


def _read(folder: Path) -> Found:
    digests = {}

    def text(name, required=False):
        path = folder / name
        if not path.is_file():
            if required:
                raise InputError(
                    "output_dir", str(folder), f"has no {name}: it is not a complete study output folder"
                )
            return None
        raw = path.read_bytes()
        digests[name] = hashlib.sha256(raw).hexdigest()
        try:
            return raw.decode()
        except UnicodeDecodeError:
            raise InputError(name, str(path), "must be UTF-8 text") from None

    def load(name, required=False, keys=()):
        raw = text(name, required)
        if raw is None:
            return None
        try:
            value = json.loads(raw)
        except ValueError as exc:
            raise InputError(name, str(folder / name), f"is not valid JSON ({exc})") from None
        if not isinstance(value, dict):
            raise InputError(name, str(folder / name), "must hold a JSON object")
        missing = [k for k in keys if k not in value]
        if missing:
            raise InputError(
                name,
                str(folder / name),
                f"has no key {missing[0]!r}: it is not the "
                "file rvte writes; run the study again to rewrite it",
            )
        return value

    manifest, inputs = load("manifest.json", True), load("inputs.json", True)
    for key in ("inputs_hash", "model_hash", "study"):
        if not isinstance(manifest.get(key), str):
            raise InputError(
                f"manifest.json {key}",
                manifest.get(key),
                "must be a text (the manifest rvte mc / rvte sobol write)",
            )
    mc = load("mc_summary.json", keys=MC_KEYS)
    samples = None
    if mc is not None and (folder / "mc_samples.csv").is_file():
        text("mc_samples.csv")
        samples = np.column_stack(read_columns("mc_samples", folder / "mc_samples.csv", tuple(mc["metrics"])))
    allocation = load("allocation.json")
    if allocation is not None:
        check_allocation(allocation, str(folder / "allocation.json"))
    return Found(
        manifest,
        inputs,
        text("study.toml") or "",
        mc,
        samples,
        load("sobol_indices.json", keys=SOBOL_KEYS),
        allocation,
        text("mc_worst_errors.toml"),
        digests,
    )


def stored_study(folder: Path, found: Found) -> Study:
    """The study that computed the store (`tolerance.study.study_from_store`): its identity
    from inputs.json, its name from the manifest, the rest from the folder's study.toml."""
    return study_from_store(folder, found.manifest["study"], found.inputs, found.study_text)


def check_allocation(values: dict, where: str) -> None:
    """Check allocation.json against its schema (docs/studies.md section 7): the first bad field."""

    def need(path, value, kind):
        ok = {
            "text": isinstance(value, str),
            "flag": isinstance(value, bool),
            "count": isinstance(value, int) and not isinstance(value, bool),
            "number": isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value),
        }[kind]
        if not ok:
            raise InputError(
                path,
                value,
                f"must be a {kind}"
                if value is not None
                else f"is missing: allocation.json needs it ({kind})",
                where,
            )

    def get(table, key):
        return table.get(key) if isinstance(table, dict) else None

    for key, kind in (
        ("study", "text"),
        ("study_file", "text"),
        ("allocated_study_file", "text"),
        ("target_yield", "number"),
        ("feasible", "flag"),
        ("model_evaluations", "count"),
    ):
        need(key, values.get(key), kind)
    factors = values.get("factors")
    if not isinstance(factors, list) or not factors:
        raise InputError("factors", factors, "must be a list of one table per factor", where)
    for i, item in enumerate(factors):
        for key, kind in (
            ("name", "text"),
            ("unit", "text"),
            ("current", "number"),
            ("allocated", "number"),
            ("lower", "number"),
            ("upper", "number"),
            ("cost_current", "number"),
            ("cost_allocated", "number"),
        ):
            need(f"factors[{i}].{key}", get(item, key), kind)
        if item.get("binding") not in ("none", "lower", "upper"):
            raise InputError(
                f"factors[{i}].binding", item.get("binding"), "must be one of none, lower, upper", where
            )
    for state in ("current", "allocated"):
        need(f"total_cost.{state}", get(values.get("total_cost"), state), "number")
        part = get(values.get("yield"), state)
        for key in ("estimate", "low", "high"):
            need(f"yield.{state}.{key}", get(part, key), "number")
        need(f"yield.{state}.n", get(part, "n"), "count")
    for key, kind in (("kind", "text"), ("samples", "count"), ("validation", "text")):
        need(f"surrogate.{key}", get(values.get("surrogate"), key), kind)


# -- is it still what the study file and the model say? --------------------------------------


@dataclass(frozen=True)
class Freshness:
    """How the stored results relate to the study file and the model as they are now.

    study_changed: None if no study file was there to compare; banners:
    (level, text) for the top of the report, the worst first.
    """

    study_file: Path | None
    current: Study | None
    study_changed: bool | None
    differing: tuple
    model_changed: bool
    inputs_consistent: bool
    banners: tuple

    @property
    def up_to_date(self) -> bool:
        """Whether the study file was there and unchanged, the model unchanged and the stored
        inputs consistent with the manifest."""
        return self.study_changed is False and not self.model_changed and self.inputs_consistent


def freshness(folder: Path, found: Found, current: Study | None, given: bool) -> Freshness:
    """Compare the store's hashes with the study file and the model as they are now.

    current: the study file given (`given`), or None: then the one at the default place.
    """
    manifest, bad, warn = found.manifest, [], []
    canonical = json.dumps(found.inputs, sort_keys=True, separators=(",", ":"))
    consistent = hashlib.sha256(canonical.encode()).hexdigest() == manifest["inputs_hash"]
    if not consistent:
        bad.append(
            "inputs.json does not hash to the manifest's inputs hash: the folder was "
            "edited by hand, and its record of the inputs cannot be trusted."
        )
    model = model_fingerprint()
    model_changed = model != manifest["model_hash"]
    if model_changed:
        bad.append(
            f"The model has changed since these results were computed (model hash "
            f"{manifest['model_hash'][:12]} then, {model[:12]} now: another rvte version, "
            "or a change to rvfmu/core or to tolerance/sampling.py, sequences.py or "
            "evaluate.py). The stored numbers are those of the old model; the nominal TE "
            "is computed with the model as it is now. Run the study again in a new output "
            "folder to update them."
        )
    path = None if current is None else Path(current.path)
    if current is None and not given:
        current, path, warning = _default_study(folder)
        if warning:
            warn.append(warning)
    changed, differing = None, ()
    if current is not None:
        ours = json.loads(json.dumps(current.inputs()))
        differing = tuple(
            sorted(k for k in set(ours) | set(found.inputs) if ours.get(k) != found.inputs.get(k))
        )
        changed = current.inputs_hash != manifest["inputs_hash"]
        if changed:
            bad.insert(
                0,
                f"The study file {path} has changed since these results were computed "
                f"(it differs in: {', '.join(differing) or 'its hash'}). The numbers below "
                "are those of the study as it was run (its copy, study.toml, is in the "
                "inputs section), not of the file as it is now. Run rvte mc / rvte sobol "
                "on it with another output folder for results of the study as it is now.",
            )
        elif current.text != found.study_text:
            warn.append(
                f"The study file {path} was edited since the last run without changing "
                "any computed number (its spec, name, sample counts or comments): both "
                "texts are in the inputs section."
            )
        spec = _spec_labels(current.spec)
        if found.mc is not None and not changed and spec != [y["limit"] for y in found.mc["yields"]]:
            warn.append(
                f"The spec of the study file now ({'; '.join(spec) or 'none'}) is not the "
                "one the Monte Carlo yields below were computed with ("
                f"{'; '.join(y['limit'] for y in found.mc['yields']) or 'none'}): run "
                "rvte mc again to re-analyse (every batch is reused)."
            )
    elif not warn:
        warn.append(
            "No study file was given to compare with (--study): whether it changed since "
            "these results were computed cannot be told; the inputs shown are those the "
            "output folder recorded."
        )
    if found.allocation is not None and found.allocation["study"] != manifest["study"]:
        warn.append(
            f"allocation.json is for study {found.allocation['study']!r}, not for "
            f"{manifest['study']!r}: its table may not belong to these results."
        )
    banners = [("bad", text) for text in bad] + [("warn", text) for text in warn]
    if not bad:
        checked = (
            f"the study file {path} and the model are those that computed these results"
            if changed is False
            else "the model is the one that computed these results"
        )
        banners.insert(
            0,
            (
                "ok",
                f"Up to date: {checked} (inputs hash "
                f"{manifest['inputs_hash'][:12]}, model hash {model[:12]}).",
            ),
        )
    return Freshness(path, current, changed, differing, model_changed, consistent, tuple(banners))


def _default_study(folder: Path):
    """(study, path, warning): NAME.toml beside NAME/output, if its output is this folder."""
    candidate = folder.parent.parent / f"{folder.parent.name}.toml"
    if folder.name != "output" or not candidate.is_file():
        return None, None, None
    try:
        study = load_study(candidate)
    except InputError as exc:
        return (
            None,
            candidate,
            (
                f"The study file {candidate} (where this output folder's study "
                f"would be) no longer loads ({exc}): whether it changed since "
                "these results were computed cannot be told."
            ),
        )
    if Path(study.output).resolve() != folder.resolve():
        return None, None, None
    return study, candidate, None


def _spec_labels(spec) -> list[str]:
    """The yield labels an analysis gives a spec: one per limit, and 'all limits' for several."""
    return [str(limit) for limit in spec] + (["all limits"] if len(spec) > 1 else [])


# -- the nominal reducer -----------------------------------------------------------------------


@dataclass(frozen=True)
class Nominal:
    """The reducer with every tolerance zero at the study's operating point.

    metrics: {column: value} by the study's own metric definitions (`evaluate`);
    curve: its TE curve at the study's load, at the study's points if they resolve the
    pin-passing order, else at 8 z_p z_c points (a figure must not alias what it shows).
    """

    metrics: dict
    curve: object
    errors: str


def nominal_reducer(study: Study) -> Nominal:
    """Every tolerance of the study set to zero: the design, plus the fixed errors if it has some."""
    zero = replace(
        study,
        factors=tuple(
            replace(
                f, position_um=0.0, cumulative_um=0.0, single_um=None, band_um=0.0, min_um=0.0, max_um=0.0
            )
            for f in study.factors
        ),
    )
    Y, _ = evaluate(zero, np.full((1, len(zero.columns)), 0.5))
    points = default_points(study.design) if aliases(study) else study.points
    curve = te_curve(study.design, study.base_errors, tau_load=-study.load_Nm, points=points)
    errors = (
        f"with the study's fixed errors ({study.errors_source or 'errors file'})"
        if study.base_errors is not None
        else "no errors: the design as drawn"
    )
    return Nominal(dict(zip(study.metric_columns, Y[0].tolist())), curve, errors)


# -- sections ------------------------------------------------------------------------------------


def _design_section(study: Study, found: Found) -> Section:
    d = study.design
    source = "" if study.design_source in ("", d.name) else f" ({study.design_source})"
    rows = [
        ("design", d.name + source),
        ("ratio, pins z_p, lobes z_c, cranks n_c", f"{d.ratio:g}, {d.z_p}, {d.z_c}, {d.n_c}"),
        ("rated torque", f"{d.rated_torque:g} N·m"),
        (
            "load",
            "none (no-load TE)"
            if study.load_Nm == 0
            else f"{study.load_Nm:g} N·m resisting"
            if study.load_Nm > 0
            else f"{-study.load_Nm:g} N·m assisting",
        ),
        (
            "points per output revolution",
            f"{study.points} ("
            + (
                f"below the pin-passing order {d.z_p * d.z_c}: see the aliasing check)"
                if aliases(study)
                else f"resolve the pin-passing order {d.z_p * d.z_c})"
            ),
        ),
        ("fixed errors", study.errors_source or "none"),
        ("metrics", ", ".join(study.metric_columns)),
        ("spec", "; ".join(str(s) for s in study.spec) or "none"),
        ("seed, batch size", f"{study.seed}, {study.batch_size}"),
    ]
    if any(m in WINDUP_METRICS for m in study.metrics):
        rows.append(("windup test positions", str(study.windup_positions)))
    if any(m in FRICTION_METRICS for m in study.metrics):
        rows.append(("output speed of the friction metrics", f"{study.output_speed_rpm:g} rpm"))
    tolerances = []
    for f in study.factors:
        values = ", ".join(f"{k} {getattr(f, k):.12g}" for k in KEYS[f.kind] if getattr(f, k) is not None)
        tolerances.append((f.name, f.kind, values, f.distribution, f.group))
    design_values = [
        (k, f"{v:.12g}" if isinstance(v, float) else str(v)) for k, v in found.inputs["design"].items()
    ]
    return Section(
        "design",
        "Design and operating point",
        [
            Table(("", ""), rows),
            Table(
                ("factor", "kind", "tolerance [µm]", "distribution", "Sobol group"),
                tolerances,
                "Tolerances (docs/studies.md section 3: zone = diameter of the true-position zone, "
                "pitch = F_p and f_pt, band = full width, clearance = range)",
            ),
            Table(
                ("design key", "value"),
                design_values,
                "Design values as the study used them (design file keys and units)",
                columns=2,
            ),
        ],
    )


def _nominal_section(study: Study, nominal: Nominal) -> Section:
    c = nominal.curve
    te = c.te_arcsec[0]
    orders, amplitudes = metrics.significant_orders(te, ORDERS_SHOWN)
    rows = [(column_label(col), Num(v)) for col, v in nominal.metrics.items()]
    rows.append(("TE mean [arcsec]", Num(float(c.mean_arcsec[0]))))
    rows += [(f"order {int(o)} amplitude [arcsec]", Num(float(a))) for o, a in zip(orders[0], amplitudes[0])]
    if not len(orders[0]):
        rows.append(("largest orders", "none above the noise floor: the TE is flat"))
    title = (
        f"{study.design.name} without tolerances: te_pp {np.ptp(te):.3f}″ at "
        f"{study.load_Nm:g} N·m, {c.points} points/rev"
    )
    return Section(
        "nominal",
        "Nominal TE",
        [
            Para(
                f"The reducer without tolerances ({nominal.errors}) at the study's operating point, "
                f"computed with the model as it is now. Its metrics follow the study's definitions; "
                f"the orders are those above the spectrum's noise floor."
            ),
            Table(("quantity", "nominal"), rows),
            Figure(
                _png(figure_te(c, title=title, zoom=True)),
                "Nominal TE over one output "
                "revolution (top), a few pin-passing periods of it where the ripple's shape shows "
                "(middle, where the points resolve it) and "
                f"its order spectrum (bottom), {nominal.errors}, at {c.points} points per "
                "revolution"
                + (
                    ""
                    if c.points == study.points
                    else f" (resolving the pin-passing order; the study's metrics use its {study.points})"
                ),
            ),
        ],
    )


def _mc_section(study: Study, found: Found, nominal: Nominal) -> Section:
    mc, src = found.mc, "mc_summary.json"
    head = ("metric", "nominal", "mean", "std", "min", *[f"p{p}" for p in PERCENTILES], "max")
    rows = []
    for column in mc["metrics"]:
        rows.append(
            (
                column,
                Num(nominal.metrics.get(column)),
                *[_json_num(mc, src, "metrics", column, k) for k in ("mean", "std", "min")],
                *[_json_num(mc, src, "metrics", column, "percentiles", str(p)) for p in PERCENTILES],
                _json_num(mc, src, "metrics", column, "max"),
            )
        )
    blocks = [
        Para(
            f"{mc['n']} reducers drawn with seed {study.seed} ({mc['evaluated']} evaluated; "
            f"{mc['computed_rows']} computed in batches of {mc['batch_size']}). "
            f"{mc['operating']}."
        ),
        Table(
            head,
            rows,
            "Distribution of each metric (nominal: the reducer without tolerances; p: percentiles)",
        ),
    ]
    yields = [
        (
            y["limit"],
            _json_num(mc, src, "yields", i, "passed", fmt="d"),
            _json_num(mc, src, "yields", i, "n", fmt="d"),
            _json_num(mc, src, "yields", i, "fraction", fmt=".2f", scale=100),
            _json_num(mc, src, "yields", i, "low", fmt=".2f", scale=100),
            _json_num(mc, src, "yields", i, "high", fmt=".2f", scale=100),
            f"{100 * y['confidence']:g} % {y['method']}",
        )
        for i, y in enumerate(mc["yields"])
    ]
    if yields:
        blocks.append(
            Table(
                ("spec limit", "passed", "n", "yield [%]", "low [%]", "high [%]", "interval"),
                yields,
                "Yield against the spec, with its interval",
            )
        )
    else:
        blocks.append(Para("The study has no [spec]: no yield.", "note"))
    if mc["failed"]:
        blocks.append(
            Para(
                f"The model failed on {mc['failed']} reducers; they are left out of "
                "every statistic and of the yield.",
                "warn",
            )
        )
    if mc["not_converged"]:
        blocks.append(Para(f"{mc['not_converged']} reducers did not converge at some angle (kept).", "warn"))
    blocks += _aliasing_blocks(mc, src)
    worst = mc["worst"]
    blocks.append(
        Para(
            f"Worst reducer: row {worst['row']} by {worst['column']}; its complete error "
            "set is mc_worst_errors.toml (inputs section), with the command that "
            "reproduces its TE.",
            "note",
        )
    )
    if found.samples is not None and found.samples.shape[0] == mc["n"]:
        figure_study = (
            study
            if _spec_labels(study.spec) == [y["limit"] for y in mc["yields"]]
            else replace(study, spec=())
        )
        analysis = MCAnalysis(
            mc["n"],
            mc["evaluated"],
            mc["failed"],
            mc["not_converged"],
            (),
            tuple(
                Yield(
                    y["limit"],
                    y["passed"],
                    y["n"],
                    y["fraction"],
                    y["low"],
                    y["high"],
                    y["confidence"],
                    y["method"],
                )
                for y in mc["yields"]
            ),
            worst["row"],
            worst["column"],
        )
        blocks.append(
            Figure(
                _png(figure_mc(figure_study, found.samples, analysis)),
                "Histogram and cumulative distribution of each metric (mc_samples.csv), spec limits dashed",
            )
        )
    else:
        blocks.append(
            Para(
                "No figure: mc_samples.csv is missing or holds another number of "
                "reducers than mc_summary.json.",
                "note",
            )
        )
    return Section("montecarlo", "Monte Carlo: distributions and yield", blocks)


def _aliasing_blocks(data: dict, src: str) -> list:
    alias = data.get("aliasing")
    if not alias:
        return []
    rows = [
        (
            c,
            _json_num(data, src, "aliasing", "max_change", c, fmt=".3g"),
            _json_num(data, src, "aliasing", "max_relative_change", c, fmt=".2f", scale=100),
        )
        for c in alias["columns"]
    ]
    blocks = [
        Table(
            ("TE metric", "largest change", "largest change [%]"),
            rows,
            f"Aliasing check: {alias['points']} points per revolution do not resolve the "
            f"pin-passing order; {alias['rows']} reducers recomputed at "
            f"{alias['full_points']} points",
        )
    ]
    risk = alias.get("yield_at_risk") or {}
    if risk:
        blocks.append(
            Table(
                ("spec limit", "reducers within that change of the limit [%]"),
                [
                    (label, _json_num(data, src, "aliasing", "yield_at_risk", label, fmt=".2f", scale=100))
                    for label in risk
                ],
                "The most aliasing can move each yield",
            )
        )
    return blocks


def _sobol_section(study: Study, found: Found) -> Section:
    s, src = found.sobol, "sobol_indices.json"
    conf = f"{100 * s['confidence']:g} %"
    blocks = [
        Para(
            f"{s['n']} base samples, {s['evaluations']} evaluations, {len(s['factors'])} "
            f"factors; S1 and ST with {conf} bootstrap intervals ({s['resamples']} "
            f"resamples){', second order' if s['second_order'] else ''}."
        )
    ]
    for column, entry in s["metrics"].items():
        blocks.append(Para(f"{column_label(column)} ({column})", "h3"))
        if entry["constant"]:
            blocks.append(Para("The metric did not vary over the sample: every index is 0.", "note"))
            continue
        rows = [
            (
                Num(g["rank"], "d"),
                g["name"],
                _json_num(s, src, "metrics", column, "groups", i, "S1_reported", fmt=".3f"),
                _json_num(s, src, "metrics", column, "groups", i, "S1_conf", fmt=".3f"),
                _json_num(s, src, "metrics", column, "groups", i, "ST_reported", fmt=".3f"),
                _json_num(s, src, "metrics", column, "groups", i, "ST_conf", fmt=".3f"),
                "; ".join(g["notes"]),
            )
            for i, g in enumerate(entry["groups"])
        ]
        total = sum(g["S1_reported"] or 0.0 for g in entry["groups"])
        blocks.append(
            Table(
                ("rank", "factor", "S1", "± CI", "ST", "± CI", "notes"),
                rows,
                f"Ranking by ST; sum S1 = {total:.3f} (1 − sum S1 = share of interactions)",
            )
        )
        if entry.get("order_groups"):
            blocks.append(
                Para(
                    f"Order: {order_text(entry['order_groups'])}. Ranks joined by "
                    f"'-' cannot be told apart: the {conf} interval of their ST "
                    "difference includes 0."
                )
            )
        conv = entry["convergence"]
        rows = [
            (
                g["name"],
                *[
                    _json_num(s, src, "metrics", column, "convergence", "ST", g["name"], k, fmt=".3f")
                    for k in range(len(conv["n"]))
                ],
            )
            for g in entry["groups"]
        ]
        state = "converged" if conv["converged"] else "NOT converged: raise n"
        blocks.append(
            Table(
                ("factor", *[f"ST at N = {m}" for m in conv["n"]]),
                rows,
                f"Convergence: max |ST(N) − ST(N/2)| = {conv['max_change_ST']:.3f} → "
                f"{state} (limit {conv['limit']})",
            )
        )
        if entry.get("S2"):
            top = sorted(entry["S2"].items(), key=lambda kv: -(kv[1]["S2"] or 0.0))[:S2_SHOWN]
            blocks.append(
                Table(
                    ("pair", "S2", "± CI"),
                    [
                        (
                            pair,
                            _json_num(s, src, "metrics", column, "S2", pair, "S2", fmt=".3f"),
                            _json_num(s, src, "metrics", column, "S2", pair, "S2_conf", fmt=".3f"),
                        )
                        for pair, _ in top
                    ],
                    "Largest second-order indices",
                )
            )
    blocks += _aliasing_blocks(s, src)
    analyses = sobol_analyses(s)
    if analyses:
        order = {column: entry.get("order_groups") for column, entry in s["metrics"].items()}
        blocks.append(
            Figure(
                _png(figure_sobol(study, analyses, order)),
                "S1 and ST of each "
                "factor with their bootstrap intervals, ranked by ST; shaded: "
                "neighbouring ranks whose order is not settled",
            )
        )
        for column, analysis in analyses.items():  # one figure per metric: readable at page width
            blocks.append(
                Figure(_png(figure_convergence(study, {column: analysis})), f"Convergence of ST for {column}")
            )
    blocks.append(Para(" ".join(line.strip() for line in NOTES_LEGEND), "note"))
    return Section("sobol", "Sobol ranking of the tolerances", blocks)


def sobol_analyses(s: dict) -> dict:
    """{column: SobolAnalysis} rebuilt from sobol_indices.json, factors in study order."""
    names = tuple(s["factors"])
    out = {}
    for column, entry in s["metrics"].items():
        if entry["constant"]:
            continue
        by_name = {g["name"]: g for g in entry["groups"]}

        def values(key):
            return np.array([np.nan if by_name[n][key] is None else by_name[n][key] for n in names])

        conv = entry["convergence"]
        out[column] = SobolAnalysis(
            column,
            Indices(
                names,
                s["n"],
                values("S1"),
                values("S1_conf"),
                values("ST"),
                values("ST_conf"),
                None,
                None,
                s["confidence"],
            ),
            Convergence(
                tuple(conv["n"]),
                np.array([conv["S1"][n] for n in names], dtype=float).T,
                np.array([conv["ST"][n] for n in names], dtype=float).T,
            ),
        )
    return out


def _allocation_section(a: dict) -> Section:
    src = "allocation.json"
    rows = [
        (
            f["name"],
            f["unit"],
            *[
                _json_num(a, src, "factors", i, k)
                for k in ("current", "allocated", "lower", "upper", "cost_current", "cost_allocated")
            ],
            f["binding"],
        )
        for i, f in enumerate(a["factors"])
    ]
    foot = [
        (
            "total",
            "",
            "",
            "",
            "",
            "",
            _json_num(a, src, "total_cost", "current"),
            _json_num(a, src, "total_cost", "allocated"),
            "",
        )
    ]
    yields = [
        (
            state,
            *[
                _json_num(a, src, "yield", state, k, fmt=".2f", scale=100)
                for k in ("estimate", "low", "high")
            ],
            _json_num(a, src, "yield", state, "n", fmt="d"),
        )
        for state in ("current", "allocated")
    ]
    sur = a["surrogate"]
    return Section(
        "allocation",
        "Tolerance allocation",
        [
            Para(
                f"Target yield {100 * a['target_yield']:.2f} %: "
                + ("feasible." if a["feasible"] else "NOT feasible within the bounds.")
                + f" Allocated study file: {a['allocated_study_file']} (from {a['study_file']})."
            ),
            Table(
                (
                    "factor",
                    "unit",
                    "current",
                    "allocated",
                    "lower bound",
                    "upper bound",
                    "cost current",
                    "cost allocated",
                    "binding",
                ),
                rows,
                "Tolerances now and allocated, their bounds and costs",
                foot,
            ),
            Table(("tolerances", "yield [%]", "low [%]", "high [%]", "n"), yields, "Yield with its interval"),
            Para(
                f"Surrogate: {sur['kind']}, {sur['samples']} samples, validation {sur['validation']}; "
                f"{a['model_evaluations']} model evaluations.",
                "note",
            ),
        ],
    )


def _inputs_section(folder: Path, study: Study, found: Found, fresh: Freshness) -> Section:
    m = found.manifest
    blocks = [
        Para(
            "Everything that produced the numbers above. The store's identity: the inputs "
            "hash is the sha256 of inputs.json (canonical JSON: every input that changes a "
            "computed number); the model hash covers the rvte version and the model's "
            "source (docs/studies.md section 5.3)."
        )
    ]
    rows = [
        ("format", m.get("format", "")),
        ("study", m["study"]),
        ("created", m.get("created", "")),
        ("inputs hash (store)", m["inputs_hash"]),
        ("inputs.json hashes to it", "yes" if fresh.inputs_consistent else "NO"),
    ]
    if fresh.current is not None:
        rows.append(("inputs hash of the study file now", fresh.current.inputs_hash))
    rows += [("model hash (store)", m["model_hash"]), ("model hash now", model_fingerprint())]
    blocks.append(Table(("", ""), rows, "Hashes and fingerprints"))
    blocks.append(
        Table(
            ("job", "batch files", "rows", "files matching their checksum", "sha256 of the batch file names"),
            job_fingerprints(folder),
            "The store: one folder per job, each batch file named by its sha256",
        )
    )
    blocks.append(
        Table(("file", "sha256"), sorted(found.digests.items()), "The files this report was made from")
    )
    blocks.append(
        Code(
            "Study file as run (study.toml in the output folder)",
            found.study_text or "(no study.toml in the output folder)",
        )
    )
    if fresh.current is not None and fresh.current.text != found.study_text:
        blocks.append(Code(f"Study file now ({fresh.study_file})", fresh.current.text))
    if study.base_errors is not None:
        blocks.append(_fixed_errors(study, found, fresh))
    if found.worst_errors:
        blocks.append(Code("Worst reducer's errors (mc_worst_errors.toml)", found.worst_errors))
    blocks.append(
        Table(
            ("package", "when the store was created", "now"),
            package_versions(found.manifest.get("versions")),
            "Software that computed the results (recorded in manifest.json when the "
            "output folder was created) and of this report; the model hash above says "
            "whether the model is the one that computed them",
        )
    )
    return Section("inputs", "Inputs, versions and hashes", blocks)


def _fixed_errors(study: Study, found: Found, fresh: Freshness) -> Code:
    """The error file as written, if it is still there with the stored values; else those values."""
    names = [fresh.current.errors_source] if fresh.current is not None else []
    for name in [*names, study.errors_source]:
        path = Path(name)
        if not name or not path.is_file():
            continue
        try:
            values = json.loads(json.dumps(error_file_values(load_errors(path, study.design))))
        except InputError:
            continue
        if values == found.inputs["errors"]:
            return Code(f"Fixed errors: {path} (the values stored in inputs.json)", path.read_text())
    return Code(
        f"Fixed errors ({study.errors_source}), as stored in inputs.json (the file is not "
        "where the study file says, or now holds other values)",
        toml_text(found.inputs["errors"], f"Fixed errors of study {study.name!r} (um, deg)"),
    )


def job_fingerprints(folder: Path) -> list:
    """Per job folder: (job, batch files, rows, files whose sha256 matches their name, digest).

    The digest is the sha256 of the sorted batch file names, each of which carries
    the first 16 hex digits of its file's sha256: one number for a job's results.
    """
    rows = []
    for job in sorted(p for p in folder.iterdir() if p.is_dir()):
        names = sorted(p.name for p in job.glob("batch-*-*-*.parquet"))
        if not names:
            continue
        matching = sum(
            hashlib.sha256((job / n).read_bytes()).hexdigest()[:FILE_DIGEST]
            == n[: -len(".parquet")].rsplit("-", 1)[-1]
            for n in names
        )
        stop = max(int(n.split("-")[2]) for n in names)
        digest = hashlib.sha256("\n".join(names).encode()).hexdigest()
        rows.append((job.name, Num(len(names), "d"), f"0–{stop}", f"{matching} of {len(names)}", digest))
    return rows


def package_versions(recorded: dict | None) -> list:
    """(package, version when computed, version now) rows; older stores recorded none."""
    now = software_versions()
    recorded = recorded if isinstance(recorded, dict) else {}
    names = list(now) + [name for name in recorded if name not in now]
    return [(name, str(recorded.get(name, "not recorded")), now.get(name, "not installed")) for name in names]


def _key_results(study: Study, found: Found, nominal: Nominal) -> Section:
    rows = [(f"nominal {column_label(c)}", Num(v), nominal.errors) for c, v in nominal.metrics.items()]
    if found.mc is not None:
        mc = found.mc
        if mc["yields"]:
            i = len(mc["yields"]) - 1  # 'all limits' when there are several
            y = mc["yields"][i]
            rows.append(
                (
                    f"yield {y['limit']} [%]",
                    _json_num(mc, "mc_summary.json", "yields", i, "fraction", fmt=".2f", scale=100),
                    f"{100 * y['low']:.2f}–{100 * y['high']:.2f} % ({100 * y['confidence']:g} "
                    f"% {y['method']} interval), {mc['n']} reducers",
                )
            )
    if found.sobol is not None:
        s = found.sobol
        for column, entry in s["metrics"].items():
            if entry["constant"]:
                continue
            top = entry["groups"][0]
            state = "converged" if entry["convergence"]["converged"] else "not converged"
            rows.append(
                (
                    f"largest ST of {column}",
                    _json_num(
                        s, "sobol_indices.json", "metrics", column, "groups", 0, "ST_reported", fmt=".3f"
                    ),
                    f"{top['name']} (± {top['ST_conf']:.3f}; N = {s['n']}, {state})",
                )
            )
    if found.allocation is not None:
        a = found.allocation
        rows.append(
            (
                "allocated yield [%]",
                _json_num(a, "allocation.json", "yield", "allocated", "estimate", fmt=".2f", scale=100),
                f"target {100 * a['target_yield']:.2f} %, "
                + ("feasible" if a["feasible"] else "NOT feasible")
                + f", cost {a['total_cost']['current']:.4g} → "
                f"{a['total_cost']['allocated']:.4g}",
            )
        )
    return Section("key", "Key results", [Table(("quantity", "value", "detail"), rows)])


def _summary(folder, study, found, fresh, nominal) -> dict:
    status = (
        "inputs.json inconsistent"
        if not fresh.inputs_consistent
        else "study file changed"
        if fresh.study_changed
        else "model changed"
        if fresh.model_changed
        else "up to date"
        if fresh.up_to_date
        else "study file not checked"
    )
    out = {
        "study": study.name,
        "output": str(folder),
        "status": status,
        "up_to_date": fresh.up_to_date,
        "study_file": None if fresh.study_file is None else str(fresh.study_file),
        "study_changed": fresh.study_changed,
        "differing": list(fresh.differing),
        "model_changed": fresh.model_changed,
        "inputs_consistent": fresh.inputs_consistent,
        "warnings": [text for level, text in fresh.banners if level != "ok"],
        "inputs_hash": found.manifest["inputs_hash"],
        "model_hash": found.manifest["model_hash"],
        "nominal": {"errors": nominal.errors, **nominal.metrics},
        "mc": None,
        "sobol": None,
        "allocation": None,
    }
    if found.mc is not None:
        out["mc"] = {
            "n": found.mc["n"],
            "yields": [
                {k: y[k] for k in ("limit", "fraction", "low", "high", "confidence")}
                for y in found.mc["yields"]
            ],
        }
    if found.sobol is not None:
        s = found.sobol
        out["sobol"] = {
            "n": s["n"],
            "evaluations": s["evaluations"],
            "ranking": {c: [g["name"] for g in e["groups"]] for c, e in s["metrics"].items()},
            "converged": {c: e["convergence"]["converged"] for c, e in s["metrics"].items()},
        }
    if found.allocation is not None:
        a = found.allocation
        out["allocation"] = {
            "feasible": a["feasible"],
            "target_yield": a["target_yield"],
            "total_cost": a["total_cost"],
            "yield": a["yield"],
        }
    return out


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=FIGURE_DPI)
    return buffer.getvalue()


# -- everything, gathered -------------------------------------------------------------------------


@dataclass(frozen=True)
class Content:
    """The report's content, for both renderers.

    banners: (level, text) for the top, the worst first (levels "bad", "warn", "ok");
    head: the key-results section, shown before the others; sections: the rest in order;
    summary: the key numbers as JSON-ready values (`StudyReport.to_json`).
    """

    title: str
    subtitle: str
    banners: tuple
    head: list
    sections: list
    summary: dict


def gather(folder: Path, current: Study | None, given: bool) -> Content:
    """Read a checked study output folder and lay out what the report shows.

    current: the study file as it is now, loaded (None: not given, then the one at the
    default place NAME.toml beside NAME/output is compared if it is there); given: whether
    a study file was given.  Runs the model once, on the nominal reducer.
    """
    found = _read(folder)
    study = stored_study(folder, found)
    fresh = freshness(folder, found, current, given)
    nominal = nominal_reducer(study)
    sections = [_design_section(study, found), _nominal_section(study, nominal)]
    if found.mc is not None:
        sections.append(_mc_section(study, found, nominal))
    if found.sobol is not None:
        sections.append(_sobol_section(study, found))
    if found.allocation is not None:
        sections.append(_allocation_section(found.allocation))
    sections.append(_inputs_section(folder, study, found, fresh))
    summary = _summary(folder, study, found, fresh, nominal)
    head = [_key_results(study, found, nominal)]
    return Content(
        f"Tolerance study {study.name!r}", operating_text(study), fresh.banners, head, sections, summary
    )
