"""`rvte presets`, `rvte presets --catalogue` and `rvte errors-template`."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from ..core.reducer.design import PRESET_NAMES, RVDesign, preset
from ..outputs import figure_file, output_file
from .common import _json_safe, resolve_design


def errors_template(design, output: str | Path | None = None) -> str:
    """A complete, commented error file for `design` (every name of docs/model.md
    section 4, zero values of the right shapes); written to `output` if given."""
    from ..core.reducer.errors import error_template_text

    output = None if output is None else output_file("output", output, ("toml",))
    text = error_template_text(resolve_design(design))
    if output is not None:
        output.write_text(text)
    return text


@dataclass(frozen=True)
class PresetInfo:
    """A shipped preset: its name, ratio, source (the seeds its first line names) and design."""

    name: str
    ratio: float
    source: str
    design: RVDesign


def presets() -> list[PresetInfo]:
    """The shipped presets with their ratios and sources."""
    infos = []
    for name in PRESET_NAMES:
        text = resources.files("rvfmu.core.reducer.presets").joinpath(f"{name}.toml").read_text()
        first = text.splitlines()[0]
        source = first.split("Source:", 1)[1].strip().rstrip(".") if "Source:" in first else ""
        design = preset(name)
        infos.append(PresetInfo(name, design.ratio, source, design))
    return infos


# The operating point of the friction figures beside the catalogue's: its rated output speed,
# the lubricant at its grade's temperature, no errors.
CATALOGUE_SPEED_RPM = 15.0


@dataclass(frozen=True)
class Losses:
    """A preset's friction figures at CATALOGUE_SPEED_RPM output, 40 C, no errors: the starting
    torque and the no-load running torque at the input [N*m], the efficiency at rated torque."""

    starting_torque_input_Nm: float
    running_torque_input_Nm: float
    efficiency_at_rated: float


@dataclass(frozen=True)
class CatalogueReport:
    """The presets against their frames' catalogue figures (`rvfmu.bench.catalogue`), and
    their friction figures (`Losses`, by preset name), which the catalogue table gives none of."""

    rows: list
    losses: dict

    def summary(self) -> str:
        """The table `rvte presets --catalogue` prints: one line a preset, torsional rigidity
        [N*m/arcmin] and lost motion [arcmin] before calibration, as shipped and in the
        catalogue, each marked ok or NO; then the fitted values of each calibration."""
        from ..bench import catalogue

        head = (
            f"{'preset':<11} {'frame':<8} {'rated N*m':>9}  {'torsional rigidity N*m/arcmin':>31}"
            f"  {'lost motion arcmin':>28}"
        )
        sub = (
            f"{'':<11} {'':<8} {'':>9}  {'estimate':>9} {'preset':>9} {'catalogue':>11}  "
            f"{'estimate':>9} {'preset':>8} {'catalogue':>9}"
        )
        lines = [head, sub]
        for r in self.rows:
            f = r.frame
            lines.append(
                f"{r.name:<11} {f.name:<8} {r.rated_torque_Nm:>9.0f}  "
                f"{r.estimate.torsional_rigidity_Nm_per_arcmin:>9.1f} "
                f"{r.calibrated.torsional_rigidity_Nm_per_arcmin:>9.1f} "
                f"{f.torsional_rigidity_Nm_per_arcmin:>7.0f} {'ok' if r.rigidity_within else 'NO':>3}  "
                f"{r.estimate.lost_motion_arcmin:>9.3f} {r.calibrated.lost_motion_arcmin:>8.3f} "
                f"{'<= ' + format(f.lost_motion_max_arcmin, 'g'):>6} {'ok' if r.lost_motion_within else 'NO':>2}"
            )
        lines += [
            "estimate: the preset before calibration (<name>-estimate); preset: as shipped, "
            "calibrated to the catalogue",
            f"ok: rigidity within {100 * catalogue.RIGIDITY_TOLERANCE:g} % of the catalogue's, "
            "lost motion within its bound (docs/model.md section 5 test, no errors)",
            f"catalogue: {catalogue.source()}",
        ]
        lines.append(
            f"{'preset':<11} {'starting N*m':>13} {'running N*m':>12} "
            f"{'efficiency':>11}   at the input; {CATALOGUE_SPEED_RPM:g} rpm output, "
            "rated torque, 40 C, no errors"
        )
        for r in self.rows:
            m = self.losses[r.name]
            lines.append(
                f"{r.name:<11} {m.starting_torque_input_Nm:>13.4g} "
                f"{m.running_torque_input_Nm:>12.4g} {100 * m.efficiency_at_rated:>10.1f} %"
            )
        lines.append(
            "catalogue: no starting torque, running torque or efficiency in the table held "
            f"({catalogue.CATALOGUE_FILE}): the model's are shown alone, not compared"
        )
        for r in self.rows:
            c = r.calibration
            if c:
                lines.append(
                    f"{r.name}: output_stiffness {c['output_stiffness']:.4g} N*m/arcmin, "
                    f"modification_scale {c['modification_scale']:.4g} "
                    f"({c['fit'].split(': ')[-1]})"
                )
        return "\n".join(lines)

    def to_json(self) -> dict:
        """The comparison for scripts (`--json`): the catalogue's source and per preset its
        frame, catalogue figures, estimate and preset figures, the two checks and its
        calibration; floats that are not finite as text ("inf", "nan")."""
        return _json_safe(
            {
                "source": self.rows[0].frame.source if self.rows else "",
                "presets": [
                    {
                        "name": r.name,
                        "frame": r.frame.name,
                        "rated_torque_Nm": r.rated_torque_Nm,
                        "catalogue": {
                            "rated_torque_Nm": r.frame.rated_torque_Nm,
                            "torsional_rigidity_Nm_per_arcmin": r.frame.torsional_rigidity_Nm_per_arcmin,
                            "lost_motion_max_arcmin": r.frame.lost_motion_max_arcmin,
                            "backlash_max_arcmin": r.frame.backlash_max_arcmin,
                        },
                        "estimate": vars(r.estimate),
                        "preset": vars(r.calibrated),
                        "rigidity_within": r.rigidity_within,
                        "lost_motion_within": r.lost_motion_within,
                        "calibration": r.calibration,
                        "losses": {
                            **vars(self.losses[r.name]),
                            "output_speed_rpm": CATALOGUE_SPEED_RPM,
                            "catalogue": None,
                        },
                    }
                    for r in self.rows
                ],
            }
        )


def losses_of(design: RVDesign) -> Losses:
    """`Losses` of `design` (`friction.efficiency_map` at CATALOGUE_SPEED_RPM and rated torque)."""
    from ..core.losses.friction import efficiency_map

    m = efficiency_map(design, None, [CATALOGUE_SPEED_RPM], [design.rated_torque])
    return Losses(
        float(m.starting_torque_input_Nm), float(m.no_load_running_torque_Nm[0]), float(m.efficiency[0, 0])
    )


def presets_catalogue(plot_path: str | Path | None = None) -> CatalogueReport:
    """Every preset's torsional rigidity and lost motion, before and after its calibration,
    beside its frame's catalogue figures; plot_path: a figure of the windup curves."""
    from ..bench import catalogue

    plot_path = None if plot_path is None else figure_file("plot", plot_path)
    rows = catalogue.against_catalogue()
    report = CatalogueReport(rows, {r.name: losses_of(preset(r.name)) for r in rows})
    if plot_path is not None:
        from ..plots import plot_catalogue

        plot_catalogue(report.rows, plot_path)
    return report
