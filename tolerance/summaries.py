"""Reports of tolerance studies for people and for scripts: tables, figures, JSON.

Reporting knows the result records and matplotlib, never the model.
Units are those of the metric columns (arcsec, arcmin, N*m/arcmin); yields and
Sobol indices are fractions, shown in % or as plain numbers.  Tables and JSON
name metrics by their columns (the spec keys of the study file); figures are
for people and name them by `column_label`.  Each figure is built by a
`figure_*` function (a matplotlib Figure, no pyplot state) and written by the
matching `plot_*` function.
"""

from __future__ import annotations

import json
import math
import re
import textwrap
from pathlib import Path

import numpy as np

from .montecarlo import PERCENTILES, MCAnalysis
from .sobol import CONVERGED_CHANGE, WIDE_CI

# Figures speak to people: a metric column is labelled by `column_label`; tables and
# JSON keep the column names, which are also the spec keys of the study file.
_LABELS = {
    "te_pp_arcsec": "TE peak-to-peak [arcsec]",
    "rms_arcsec": "TE RMS about the mean [arcsec]",
    "lost_motion_arcmin": "lost motion [arcmin]",
    "torsional_rigidity_Nm_per_arcmin": "torsional rigidity [N·m/arcmin]",
    "efficiency": "efficiency (forward)",
    "no_load_running_torque_Nm": "no-load running torque at the input [N·m]",
}
_ORDER_COLUMN = re.compile(r"order_([0-9]+)_arcsec$")


def operating_text(study) -> str:
    """Load and points per revolution, and whether they resolve the pin-passing order."""
    d = study.design
    load = "no load" if study.load_Nm == 0 else f"load {study.load_Nm:g} N*m resisting"
    if {"efficiency", "no_load_running_torque"} & set(study.metrics):
        load += f" at {study.output_speed_rpm:g} rpm output, the lubricant at {study.temperature_C:g} C"
    pin_order = d.z_p * d.z_c
    nyquist = study.points // 2
    resolve = (
        f"resolves the pin-passing order {pin_order}"
        if nyquist > pin_order
        else f"below the pin-passing order {pin_order}: its effect is measured by the aliasing check"
    )
    return f"{d.name}, {load}, {study.points} points per output revolution ({resolve})"


def column_label(column: str) -> str:
    """A column as people read it, with unit: 'te_pp_arcsec' -> 'TE peak-to-peak [arcsec]'.

    order_<k>_arcsec -> 'TE order <k> amplitude [arcsec]'; an unknown column is returned as is.
    """
    if column in _LABELS:
        return _LABELS[column]
    order = _ORDER_COLUMN.match(column)
    return f"TE order {int(order.group(1))} amplitude [arcsec]" if order else column


def _limit_label(limit) -> str:
    """A spec limit for a figure legend: 'spec <= 30 arcsec' (its axis names the metric)."""
    label = column_label(limit.column)
    unit = label[label.rfind("[") + 1 : -1] if label.endswith("]") else ""
    sense = "≤" if limit.sense == "max" else "≥"
    return f"spec {sense} {limit.limit:g} {unit}".rstrip()


def _suptitle(fig, text: str) -> None:
    """A figure title wrapped to the figure's width (9 pt: about 13 characters per inch)."""
    fig.suptitle(textwrap.fill(text, width=int(13 * fig.get_figwidth())), fontsize=9)


# -- Monte Carlo ------------------------------------------------------------------------------


def mc_table(study, analysis: MCAnalysis, computed=None, aliasing=None) -> str:
    """The distribution of every metric, the yields and the worst reducer, as text.

    computed: the run's `Computed` record (how many reducers were computed, in
    which batches); aliasing: the run's `AliasingCheck`, if the points alias.
    """
    a = analysis
    counted = f"{a.n} reducers analysed"
    if computed is not None:
        counted += (
            f" ({computed.Y.shape[0]} computed in {computed.batches} batches of "
            f"{computed.batch_size}"
            + ("; the rest are kept for a larger -n)" if computed.Y.shape[0] > a.n else ")")
        )
    lines = [
        f"Monte Carlo of study {study.name!r}: {counted} (seed {study.seed})",
        f"  {operating_text(study)}",
    ]
    heads = ["mean", "std", "min"] + [f"p{p}" for p in PERCENTILES] + ["max"]
    width = max(len(c) for c in study.metric_columns) + 2
    lines.append(f"  {'metric':<{width}}" + "".join(f"{h:>10}" for h in heads))
    for s in a.summaries:
        values = [s.mean, s.std, s.minimum] + [s.percentiles[p] for p in PERCENTILES] + [s.maximum]
        lines.append(f"  {s.column:<{width}}" + "".join(f"{v:>10.4g}" for v in values))
    for y in a.yields:
        lines.append(
            f"  yield {y.label}: {y.passed}/{y.n} = {100 * y.fraction:.2f} % "
            f"({100 * y.confidence:g} % {y.method} interval {100 * y.low:.2f} - "
            f"{100 * y.high:.2f} %)"
        )
    if not a.yields:
        lines.append("  no [spec] in the study: no yield")
    if a.failed:
        lines.append(f"  warning: the model failed on {a.failed} reducers; they are left out")
    if a.not_converged:
        lines.append(f"  warning: {a.not_converged} reducers did not converge at some angle")
    if aliasing is not None:
        lines += ["  " + line for line in aliasing.lines()]
    return "\n".join(lines)


def mc_json(study, analysis: MCAnalysis, extra: dict) -> dict:
    """A Monte Carlo study's summary for scripts: per metric mean, std, min, max and
    percentiles in the column's unit, the yields with their intervals, the worst reducer,
    and the keys of `extra`."""
    a = analysis
    return {
        "study": study.name,
        "job": "mc",
        "inputs_hash": study.inputs_hash,
        "operating": operating_text(study),
        "n": a.n,
        "evaluated": a.evaluated,
        "failed": a.failed,
        "not_converged": a.not_converged,
        "metrics": {
            s.column: {
                "mean": s.mean,
                "std": s.std,
                "min": s.minimum,
                "max": s.maximum,
                "percentiles": {str(p): v for p, v in s.percentiles.items()},
            }
            for s in a.summaries
        },
        "yields": [
            {
                "limit": y.label,
                "passed": y.passed,
                "n": y.n,
                "fraction": y.fraction,
                "low": y.low,
                "high": y.high,
                "confidence": y.confidence,
                "method": y.method,
            }
            for y in a.yields
        ],
        "worst": {"row": a.worst, "column": a.worst_column},
        **extra,
    }


def figure_mc(study, Y: np.ndarray, analysis: MCAnalysis):
    """Histogram (left) and empirical CDF (right) of every metric, spec limits marked: a Figure.

    Y: (n, M) in the study's metric columns; one row of two panels per column.
    """
    from matplotlib.figure import Figure

    M = len(study.metric_columns)
    fig = Figure(figsize=(10, 3.2 * M), layout="constrained")
    axes = fig.subplots(M, 2, squeeze=False)
    limits = {s.column: s for s in study.spec}
    for j, column in enumerate(study.metric_columns):
        v = np.sort(Y[np.isfinite(Y[:, j]), j])
        label = column_label(column)
        ax_h, ax_c = axes[j]
        ax_h.hist(v, bins=max(10, min(60, int(np.sqrt(v.size)) + 1)), color="C0", alpha=0.8)
        ax_h.set_xlabel(label)
        ax_h.set_ylabel("reducers")
        ax_h.set_title(f"{label}: distribution", fontsize=9)
        ax_c.step(v, np.arange(1, v.size + 1) / max(v.size, 1), where="post", color="C0")
        ax_c.set_xlabel(label)
        ax_c.set_ylabel("fraction of reducers ≤ value")
        ax_c.set_ylim(0, 1.02)
        ax_c.set_title(f"{label}: cumulative", fontsize=9)
        if column in limits:
            limit = limits[column]
            for ax in (ax_h, ax_c):
                ax.axvline(limit.limit, color="C3", ls="--", lw=1.0, label=_limit_label(limit))
            y = next((y for y in analysis.yields if y.label == str(limit)), None)
            if y is not None:
                ax_c.set_title(
                    f"{label}: yield {100 * y.fraction:.1f} % ({100 * y.low:.1f}-"
                    f"{100 * y.high:.1f} %, {100 * y.confidence:g} % Wilson)",
                    fontsize=9,
                )
            ax_h.legend(fontsize=8)
        for ax in (ax_h, ax_c):
            ax.grid(alpha=0.3)
    _suptitle(fig, f"{study.name}: {analysis.n} reducers — {operating_text(study)}")
    return fig


def plot_mc(study, Y: np.ndarray, analysis: MCAnalysis, path: Path) -> Path:
    """Histogram and empirical CDF of every metric, spec limits marked (`figure_mc`), to `path`."""
    figure_mc(study, Y, analysis).savefig(path, dpi=120)
    return Path(path)


# -- Sobol ------------------------------------------------------------------------------------

# What the notes of the Sobol table mean (tolerance.sobol, "Reading the estimates").
NOTES_LEGEND = (
    "Notes:",
    "  < 0 within its CI: negative estimates are sampling noise around zero: reported as 0 "
    "(SALib's maintainers' advice when the CI includes 0).",
    "  < 0 beyond its CI / > 1: reported as 0 / 1; beyond the CI the estimate has not converged: raise n.",
    "  S1 > ST beyond their CIs: the true S1 never exceeds ST (ST adds the interactions), so "
    "this is sampling noise: raise n.",
    f"  CI wide: the interval is wider than +-{WIDE_CI:g}; factors whose indices differ by less "
    "cannot be ranked.",
    "  order: two neighbouring ranks are told apart where the CI of their ST difference (over "
    "the same bootstrap resamples) excludes 0; their own CIs may overlap even then, since both "
    "estimates come from the same rows and move together.",
)


def sobol_table(study, analyses: dict, n: int, evaluations: int, second_order: bool) -> str:
    """Ranking table of every metric, with intervals, notes and the convergence check."""
    lines = [
        f"Sobol ranking of study {study.name!r}: {n} base samples, {evaluations} evaluations, "
        f"{len(study.groups)} factors",
        f"  {operating_text(study)}",
    ]
    for column, result in analyses.items():
        ind, conv = result.indices, result.convergence
        conf = f"{100 * ind.confidence:g} %"
        lines.append("")
        lines.append(
            f"{column}  (S1, ST with {conf} bootstrap CI, {study.resamples} resamples)"
            + (
                "; Saltelli's design evaluated on the TE linearized in the errors, "
                f"check Q2 = {result.check_q2:.4f}"
                if result.method == "linearized"
                else ""
            )
        )
        if ind.constant:
            lines.append("  the metric did not vary over the sample: every index is 0")
            continue
        width = max(len(g) for g in ind.names) + 2
        lines.append(f"  {'rank':>4}  {'factor':<{width}}{'S1':>16}{'ST':>16}  notes")
        flags = ind.flags()
        for rank, g in enumerate(ind.ranking(), start=1):
            s1 = f"{ind.S1_reported[g]:.3f} ± {ind.S1_conf[g]:.3f}"
            st = f"{ind.ST_reported[g]:.3f} ± {ind.ST_conf[g]:.3f}"
            lines.append(f"  {rank:>4}  {ind.names[g]:<{width}}{s1:>16}{st:>16}  " + "; ".join(flags[g]))
        lines.append(f"  sum S1 = {ind.S1_reported.sum():.3f} (1 - sum S1 = share of interactions)")
        groups = ind.order_groups()
        if groups is not None:
            lines.append(
                f"  order: {order_text(groups)}  (ranks joined by '-' cannot be told "
                f"apart: the {conf} CI of their ST difference includes 0)"
            )
            loose = [(rank, step) for rank, step in enumerate(ind.order(), start=1) if not step.settled]
            if loose:
                lines.append(
                    "  not settled: "
                    + ", ".join(
                        f"{rank}~{rank + 1} {step.difference:+.3f} ± {step.half_width:.3f}"
                        for rank, step in loose
                    )
                )
        changes = ", ".join(f"N={m}" for m in conv.n)
        state = "converged" if conv.converged else "NOT converged: raise n"
        lines.append(
            f"  convergence ({changes}): max |ST(N) - ST(N/2)| = {conv.max_change:.3f} "
            f"-> {state} (limit {CONVERGED_CHANGE})"
        )
        if second_order and ind.S2 is not None:
            pairs = [
                (ind.S2[a, b], ind.names[a], ind.names[b])
                for a in range(len(ind.names))
                for b in range(a + 1, len(ind.names))
            ]
            top = sorted(pairs, key=lambda p: -p[0])[:5]
            lines.append("  largest S2: " + ", ".join(f"{a} x {b} {v:.3f}" for v, a, b in top))
    lines.append("")
    lines += ["  " + line for line in NOTES_LEGEND]
    return "\n".join(lines)


def order_text(groups) -> str:
    """Runs of ranks whose order is not settled (`Indices.order_groups`): "1 | 2-3 | 4"."""
    return " | ".join(str(g[0]) if len(g) == 1 else f"{g[0]}-{g[-1]}" for g in groups)


def sobol_json(study, analyses: dict, n: int, evaluations: int, second_order: bool, extra: dict) -> dict:
    """A Sobol study's summary for scripts: per metric column of `analyses`, every group's
    rank, S1 and ST with their intervals and notes, and the keys of `extra`; n base samples,
    `evaluations` model runs."""
    metrics = {}
    for column, result in analyses.items():
        ind, conv = result.indices, result.convergence
        flags = ind.flags()
        rank_of = {int(g): r for r, g in enumerate(ind.ranking(), start=1)}
        steps = {step.upper: step for step in ind.order() or ()}
        groups = [
            {
                "name": name,
                "rank": rank_of[g],
                "S1": _num(ind.S1[g]),
                "S1_conf": _num(ind.S1_conf[g]),
                "ST": _num(ind.ST[g]),
                "ST_conf": _num(ind.ST_conf[g]),
                "S1_reported": _num(ind.S1_reported[g]),
                "ST_reported": _num(ind.ST_reported[g]),
                "notes": flags[g],
                "next": _step_json(ind, steps.get(g)),
            }
            for g, name in enumerate(ind.names)
        ]
        groups.sort(key=lambda item: item["rank"])
        entry = {
            "constant": ind.constant,
            "groups": groups,
            "order_groups": ind.order_groups(),
            "method": result.method,
            "check_q2": _num(result.check_q2) if result.check_q2 is not None else None,
            "convergence": {
                "n": list(conv.n),
                "ST": {name: [_num(v) for v in conv.ST[:, g]] for g, name in enumerate(ind.names)},
                "S1": {name: [_num(v) for v in conv.S1[:, g]] for g, name in enumerate(ind.names)},
                "max_change_ST": _num(conv.max_change),
                "converged": bool(conv.converged),
                "limit": CONVERGED_CHANGE,
            },
        }
        if second_order and ind.S2 is not None:
            entry["S2"] = {
                f"{ind.names[a]} x {ind.names[b]}": {
                    "S2": _num(ind.S2[a, b]),
                    "S2_conf": _num(ind.S2_conf[a, b]),
                }
                for a in range(len(ind.names))
                for b in range(a + 1, len(ind.names))
            }
        metrics[column] = entry
    return {
        "study": study.name,
        "job": "sobol",
        "inputs_hash": study.inputs_hash,
        "operating": operating_text(study),
        "n": n,
        "second_order": second_order,
        "evaluations": evaluations,
        "resamples": study.resamples,
        "confidence": study.sobol_confidence,
        "factors": list(study.groups),
        "metrics": metrics,
        **extra,
    }


def _step_json(ind, step) -> dict | None:
    """A group's order over the next rank (`sobol.RankStep`) for sobol_indices.json."""
    if step is None:
        return None
    return {
        "factor": ind.names[step.lower],
        "difference": _num(step.difference),
        "half_width": _num(step.half_width),
        "kept": _num(step.kept),
        "settled": step.settled,
    }


def figure_sobol(study, analyses: dict, runs: dict | None = None):
    """S1 and ST bars (reported values) with bootstrap intervals, a panel per metric: a Figure.

    analyses: {column: SobolAnalysis}; factors ranked by ST, named as in the study file.
    Runs of neighbouring ranks whose order is not settled are shaded: runs {column: runs of
    ranks (`Indices.order_groups`)}, by default those of the indices where they carry their
    bootstrap resamples.
    """
    from matplotlib.figure import Figure

    M = len(analyses)
    G = len(study.groups)
    fig = Figure(figsize=(max(7, 0.9 * G + 3), 3.6 * M), layout="constrained")
    axes = fig.subplots(M, 1, squeeze=False)
    for ax, (column, result) in zip(axes[:, 0], analyses.items(), strict=True):
        ind = result.indices
        order = ind.ranking()
        x = np.arange(len(order))
        ax.bar(
            x - 0.2,
            ind.S1_reported[order],
            0.4,
            yerr=ind.S1_conf[order],
            capsize=3,
            label="S1 (alone)",
            color="C0",
        )
        ax.bar(
            x + 0.2,
            ind.ST_reported[order],
            0.4,
            yerr=ind.ST_conf[order],
            capsize=3,
            label="ST (with interactions)",
            color="C1",
        )
        shaded = (runs or {}).get(column) or ind.order_groups() or []
        label = "ranks whose order is not settled"
        for run in shaded:
            if len(run) > 1:  # rank r sits at x = r - 1; a gap keeps neighbouring runs apart
                ax.axvspan(run[0] - 1.45, run[-1] - 0.55, color="0.87", zorder=0, label=label)
                label = None
        ax.set_xticks(x, [ind.names[g] for g in order], rotation=30, ha="right", fontsize=8)
        ax.set_xlabel("tolerance factors, ranked by ST")
        ax.set_ylabel("Sobol index (share of variance)")
        ax.set_ylim(0, 1.05)
        ax.set_title(
            f"{column_label(column)}: {100 * ind.confidence:g} % bootstrap intervals, N = {ind.n}", fontsize=9
        )
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    _suptitle(fig, f"{study.name}: {operating_text(study)}")
    return fig


def plot_sobol(study, analyses: dict, path: Path) -> Path:
    """S1 and ST bars with their bootstrap intervals, one panel per metric (`figure_sobol`)."""
    figure_sobol(study, analyses).savefig(path, dpi=120)
    return Path(path)


def figure_convergence(study, analyses: dict):
    """ST of every factor against the base samples N/4, N/2, N, a panel per metric: a Figure."""
    from matplotlib.figure import Figure

    M = len(analyses)
    fig = Figure(figsize=(5.5 * M + 2.5, 4), layout="constrained")
    axes = fig.subplots(1, M, squeeze=False)
    for ax, (column, result) in zip(axes[0], analyses.items(), strict=True):
        conv = result.convergence
        for g, name in enumerate(result.indices.names):
            ax.plot(conv.n, conv.ST[:, g], "o-", ms=3, lw=1, label=name)
        ax.set_xscale("log", base=2)
        ax.set_xticks(conv.n, [str(m) for m in conv.n])
        ax.minorticks_off()
        ax.set_xlabel("base samples N")
        ax.set_ylabel("total Sobol index ST")
        ax.set_title(
            f"{column_label(column)}: ST moves by at most {conv.max_change:.3f} from N/2 to N", fontsize=9
        )
        ax.grid(alpha=0.3)
    axes[0, -1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1.02, 0.5))
    _suptitle(fig, f"{study.name}: convergence of the Sobol ranking")
    return fig


def plot_convergence(study, analyses: dict, path: Path) -> Path:
    """ST of every factor against the base sample count N/4, N/2, N (`figure_convergence`)."""
    figure_convergence(study, analyses).savefig(path, dpi=120)
    return Path(path)


# -- files ------------------------------------------------------------------------------------


def write_json(path: Path, data: dict) -> Path:
    """Write `data` to `path` as indented JSON (numpy numbers and arrays as plain ones);
    returns the path."""
    Path(path).write_text(json.dumps(data, indent=1, default=_json_default) + "\n")
    return Path(path)


def _num(value) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")
