"""The `rvte` command line: each sub-command is a few lines over `rvfmu.api`.

Bad input never shows a traceback: it prints one line naming the field, the
value and what is allowed, and exits with status 2.

Other packages add their commands through the entry-point group
`rvte.commands` (the tolerance studies declare theirs in pyproject.toml): each
entry is a function add(subparsers) that is found and called when the parser
is built, so that `rvfmu` never imports the packages built on top of it.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from importlib import metadata

from .core.base.checks import InputError

try:
    from . import api
except InputError as exc:  # a bad RVTE_LAWS, met as the core loads (rvfmu/core/base/compiled.py)
    print(f"rvte: error: {exc}", file=sys.stderr)
    raise SystemExit(2) from None
from .progress import ProgressBar

COMMAND_GROUP = "rvte.commands"


def _te(args):
    with ProgressBar("te") as bar:
        report = api.te(
            args.design,
            args.errors,
            load=args.load,
            points=args.points,
            csv_path=args.csv,
            plot_path=args.plot,
            progress=bar,
        )
    _show(report, False, (("csv", args.csv), ("plot", args.plot)))


def _show(report, as_json: bool, files) -> None:
    """A job's summary (or its JSON, for scripts), then the files it wrote."""
    if as_json:
        import json

        print(json.dumps(report.to_json(), indent=1))
        return
    print(report.summary())
    for label, path in files:
        if path:
            print(f"wrote {label:<13} {path}")


def _presets(args):
    if args.catalogue:
        _show(api.presets_catalogue(plot_path=args.plot), args.json, (("plot", args.plot),))
        return
    print(f"{'preset':<12} {'ratio':>6}  source")
    for info in api.presets():
        print(f"{info.name:<12} {info.ratio:>6g}  {info.source}")


def _profile(args):
    prof = api.profile(args.design, csv_path=args.csv, dxf_path=args.dxf, points=args.points)
    for label, path in (("csv", args.csv), ("dxf", args.dxf)):
        if path:
            print(f"wrote {label} {path} ({prof.x.size} points, mm)")


def _simulate(args):
    with ProgressBar("simulate", unit="step") as bar:
        report = api.simulate(
            args.design,
            args.errors,
            speed_rpm=args.speed_rpm,
            load=args.load,
            duration=args.duration,
            revolutions=args.revolutions,
            contact=args.contact,
            mesh=args.mesh,
            step=args.step,
            csv_path=args.csv,
            plot_path=args.plot,
            progress=bar,
            load_step=args.load_step,
            load_csv=args.load_csv,
            input_csv=args.input_csv,
            friction=not args.no_friction,
            temperature_C=args.temperature,
        )
    _show(report, args.json, (("csv", args.csv), ("plot", args.plot)))


def _modes(args):
    report = api.modes(
        args.design,
        args.errors,
        load=args.load,
        speed_rpm=args.speed_rpm,
        count=args.count,
        plot_path=args.plot,
    )
    _show(report, args.json, (("plot", args.plot),))


def _stiffness(args):
    report = api.stiffness(args.design, args.errors, load=args.load, plot_path=args.plot)
    _show(report, args.json, (("plot", args.plot),))


def _efficiency(args):
    with ProgressBar("efficiency") as bar:
        report = api.efficiency(
            args.design,
            args.errors,
            speeds=args.speeds,
            loads=args.loads,
            plot_path=args.plot,
            progress=bar,
            temperature_C=args.temperature,
        )
    _show(report, args.json, (("plot", args.plot),))


def _hysteresis(args):
    with ProgressBar("hysteresis") as bar:
        report = api.hysteresis(
            args.design, args.errors, max_load=args.max_load, plot_path=args.plot, progress=bar
        )
    _show(report, args.json, (("plot", args.plot),))


def _errors(args):
    text = api.errors_template(args.template, args.output)
    if args.output:
        print(f"wrote error template {args.output} (every error of docs/model.md section 4, zero)")
    else:
        sys.stdout.write(text)


def _measure(args):
    report = api.measure(
        args.data,
        args.ratio,
        columns=args.columns,
        units=args.units,
        counts_per_rev=args.counts_per_rev,
        remove_orders=args.remove_orders,
        remove_input_orders=args.remove_input_orders,
        keep_orders=args.keep_orders,
        csv_path=args.csv,
        plot_path=args.plot,
    )
    _show(report, args.json, (("csv", args.csv), ("plot", args.plot)))


def _names(text: str) -> tuple[str, ...]:
    """A,B[,C] of --columns."""
    return tuple(name.strip() for name in text.split(","))


def _numbers(text: str) -> tuple[float, ...]:
    """N[,N] of --counts-per-rev."""
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected N or N_IN,N_OUT, e.g. 131072") from None


def _design_and_errors(p) -> None:
    """The design and --errors arguments that the jobs on one reducer share."""
    p.add_argument("design", help="preset name (see `rvte presets`) or design TOML file")
    p.add_argument(
        "--errors",
        help="error TOML file: the names of docs/model.md section 4, in um "
        "and deg (`rvte errors --template DESIGN` writes one to fill)",
    )


def _values(text: str) -> tuple[float, ...]:
    """X[,X...] of --speeds and --loads."""
    try:
        return tuple(float(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected numbers separated by commas, e.g. 5,15,30"
        ) from None


def _orders(text: str) -> tuple[int, ...]:
    """K[,K...] of the --*-orders options; "none" or "" for none."""
    if text.strip().lower() in ("", "none"):
        return ()
    try:
        return tuple(int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected whole orders K[,K...], e.g. 1,2, or none"
        ) from None


def _time_and_load(text: str) -> tuple[float, float]:
    """TIME_S:NM of --load-step."""
    try:
        at, value = (float(x) for x in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected TIME_S:NM, e.g. 0.3:400") from None
    return at, value


def _reducer_arguments(p, load_help: str) -> None:
    """DESIGN, --errors and --load: the reducer and its operating point, as every model takes them."""
    _design_and_errors(p)
    p.add_argument("--load", type=float, default=0.0, help=load_help)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rvte", description="Transmission error of RV reducers from design and manufacturing errors."
    )
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("te", help="TE curve over one output revolution")
    _reducer_arguments(p, "resisting output torque in N*m (0: no-load limit; negative: the load drives)")
    p.add_argument(
        "--points",
        type=int,
        help="points per output revolution (default: 8 per pin-passing period, 8*z_p*z_c)",
    )
    p.add_argument("--csv", help="write theta_in_rad,theta_out_rad,te_arcsec")
    p.add_argument("--plot", help="write a PNG of the TE curve and its order spectrum")
    p.set_defaults(run=_te)

    p = sub.add_parser("presets", help="list the shipped reducer presets")
    p.add_argument(
        "--catalogue",
        action="store_true",
        help="torsional rigidity and lost motion of each preset (before and after its "
        "calibration) beside its frame's catalogue figures",
    )
    p.add_argument("--json", action="store_true", help="with --catalogue: print it as JSON")
    p.add_argument("--plot", help="with --catalogue: write a figure of the windup curves (PNG, SVG, PDF)")
    p.set_defaults(run=_presets)

    p = sub.add_parser(
        "simulate", help="dynamic TE in time at a constant input speed (docs/model.md section 7)"
    )
    _reducer_arguments(p, "resisting output torque [N*m]")
    p.add_argument(
        "--speed-rpm",
        type=float,
        default=1600.0,
        help="input speed after the start ramp [rpm] (default 1600, as seeds 000/001)",
    )
    length = p.add_mutually_exclusive_group()
    length.add_argument(
        "--duration",
        type=float,
        help="seconds at constant speed after the ramp "
        "(an excitation's amplitude needs 4 of its periods and more: the table "
        "says how long; at most 1e6 time steps in all)",
    )
    length.add_argument("--revolutions", type=float, help="output revolutions at constant speed (default 1)")
    p.add_argument(
        "--contact",
        choices=("linear", "hertz", "impact"),
        help="pin-disc contact law (default: the design's own, hertz where it gives "
        "the pins' groove, else linear; impact: k*delta^e with ramped damping)",
    )
    p.add_argument(
        "--mesh",
        choices=("varying", "constant"),
        default="varying",
        help="sun-planet mesh stiffness over the mesh cycle",
    )
    p.add_argument(
        "--step", type=float, help="time step [s] (default: 20 per period of the fastest excitation)"
    )
    load = p.add_mutually_exclusive_group()
    load.add_argument(
        "--load-step",
        type=_time_and_load,
        metavar="TIME_S:NM",
        help="the load changes from --load to NM at TIME_S seconds of the run "
        "(t = 0 at the start of the ramp; a time outside the run is refused)",
    )
    load.add_argument(
        "--load-csv",
        metavar="FILE",
        help="load in time: columns time_s,load_Nm (linear between rows, held beyond)",
    )
    p.add_argument(
        "--input-csv",
        metavar="FILE",
        help="input angles in time instead of the ramp "
        "and --speed-rpm: columns time_s,theta_in_rad (a cubic spline through them)",
    )
    p.add_argument(
        "--no-friction",
        action="store_true",
        help="leave out the contacts' friction and drag (docs/model.md section 9): the frictionless reducer",
    )
    p.add_argument(
        "--temperature",
        type=float,
        default=40.0,
        help="lubricant temperature [C], -40 to 150 (default 40): the viscosity of the "
        "bearings' drag and the churning",
    )
    p.add_argument("--csv", help="write time_s,theta_in_rad,theta_out_rad,te_arcsec,tau_in_Nm")
    p.add_argument("--plot", help="write a figure of TE(t) and its spectrum in Hz")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=_simulate)

    p = sub.add_parser(
        "modes",
        help="natural frequencies at the loaded equilibrium beside the "
        "excitations at a speed; Campbell diagram",
    )
    _reducer_arguments(p, "resisting output torque [N*m] (0: a probe of 1e-3 x rated closes the contacts)")
    p.add_argument(
        "--speed-rpm",
        type=float,
        default=1600.0,
        help="input speed whose excitations are listed (default 1600)",
    )
    p.add_argument("--count", type=int, default=12, help="modes to list (default 12)")
    p.add_argument("--plot", help="write a Campbell diagram (0 to 1.25 x the speed)")
    p.add_argument("--json", action="store_true", help="print the modes as JSON")
    p.set_defaults(run=_modes)

    p = sub.add_parser(
        "stiffness",
        help="torsional rigidity, lost motion and the compliance "
        "budget: every elastic element's share of the windup",
    )
    _design_and_errors(p)
    p.add_argument(
        "--load",
        type=float,
        default=None,
        help="torque [N*m] whose 50-100 %% span the "
        "budget covers, in both senses (default: the rated torque, the catalogue's range)",
    )
    p.add_argument("--plot", help="write a figure of the shares and the windup curve")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(run=_stiffness)

    p = sub.add_parser(
        "efficiency",
        help="efficiency forward and backdriving over output speed "
        "and torque, no-load running, starting and backdriving torque",
    )
    _design_and_errors(p)
    p.add_argument(
        "--speeds",
        type=_values,
        default=None,
        help="output speeds [rpm], comma-separated (default 5,10,15,20,30,40,60)",
    )
    p.add_argument(
        "--loads",
        type=_values,
        default=None,
        help="resisting output torques [N*m], comma-separated (default 25, 50, 75 and 100 %% of rated)",
    )
    p.add_argument(
        "--temperature",
        type=float,
        default=40.0,
        help="lubricant temperature [C], -40 to 150 (default 40: the viscosity of its "
        "ISO VG grade; a stated lubricant_viscosity_cSt holds at every temperature)",
    )
    p.add_argument("--plot", help="write the efficiency chart and the running torque")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(run=_efficiency)

    p = sub.add_parser(
        "hysteresis",
        help="the hysteresis loop of the windup test with friction: "
        "lost motion, rigidity, hysteresis loss and the friction work by contact",
    )
    _design_and_errors(p)
    p.add_argument(
        "--max-load",
        type=float,
        default=None,
        help="the sweep's end [N*m], in both senses (default: the rated torque)",
    )
    p.add_argument(
        "--plot",
        help="write the loop as a figure, with its branches apart around "
        "zero torque and its width against torque",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(run=_hysteresis)

    p = sub.add_parser(
        "measure", help="TE from a bench's input and output encoder angles, the bench's runout removed"
    )
    p.add_argument(
        "data",
        help="CSV with a header: time_s (optional), theta_in_deg, theta_out_deg "
        "(or _rad, _counts: the unit from the suffix)",
    )
    _record_arguments(
        p,
        ratio_help="the reducer's ratio i (checked against the data: more than 1 %% off is refused)",
        required=True,
    )
    p.add_argument(
        "--csv", help="write [time_s,]theta_in_rad,theta_out_rad,te_arcsec,runout_arcsec,te_reducer_arcsec"
    )
    p.add_argument("--plot", help="write a figure of the TE and its spectra (by order, in Hz)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=_measure)
    add_model_data_commands(sub)

    p = sub.add_parser("errors", help="write a complete error file to fill in")
    p.add_argument(
        "--template",
        metavar="DESIGN",
        required=True,
        help="preset name or design TOML file: every error of docs/model.md section 4 "
        "with zero values of the design's shapes",
    )
    p.add_argument("-o", "--output", help="TOML file to write (default: standard output)")
    p.set_defaults(run=_errors)

    p = sub.add_parser("profile", help="write the cycloid disc profile")
    p.add_argument("design", help="preset name or design TOML file")
    p.add_argument("--csv", help="write x_mm,y_mm")
    p.add_argument("--dxf", help="write a DXF polyline in mm (needs ezdxf)")
    p.add_argument("--points", type=int, help="points on the profile")
    p.set_defaults(run=_profile)

    from .fmu.cli import add_fmu_commands

    add_fmu_commands(sub)
    add_plugin_commands(sub)
    return parser


def add_plugin_commands(subparsers) -> None:
    """Call every add(subparsers) of the `rvte.commands` entry-point group.

    A plugin that cannot be loaded (its package is missing or broken) costs its
    own commands only: one line on stderr says which and why.
    """
    for entry in sorted(metadata.entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            entry.load()(subparsers)
        except Exception as exc:  # noqa: BLE001 - any failure of a plugin's import or set-up
            print(
                f"rvte: the {entry.name!r} commands ({entry.value}) are unavailable: "
                f"{type(exc).__name__}: {exc}",
                file=sys.stderr,
            )


# A value that starts like a negative number: -5, -.5, -5,10, -1e3, -0.1:400.  argparse
# takes only -5 and -.5 (its _negative_number_matcher) for values; anything else after an
# option it takes for another option ("expected one argument").
NEGATIVE_VALUE = re.compile(r"-\.?\d")


def negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """`argv` with every option that takes one value and is followed by a value starting
    like a negative number (`--speeds -5,10`) joined to it (`--speeds=-5,10`), which argparse
    always reads as the option's value; the sub-command's own options are looked up, so
    nothing else changes."""
    out, current, k = [], parser, 0
    while k < len(argv):
        token = argv[k]
        out.append(token)
        k += 1
        if token == "--":
            out += argv[k:]
            break
        chosen = next(
            (
                a.choices[token]
                for a in current._actions
                if isinstance(a, argparse._SubParsersAction) and token in a.choices
            ),
            None,
        )
        if chosen is not None:
            current = chosen
            continue
        action = current._option_string_actions.get(token)
        if action is None and token.startswith("--") and current.allow_abbrev:
            # an abbreviation argparse would accept (--speed for --speeds): its one action
            found = {id(a): a for o, a in current._option_string_actions.items() if o.startswith(token)}
            action = next(iter(found.values())) if len(found) == 1 else None
        if action is not None and action.nargs is None and k < len(argv) and NEGATIVE_VALUE.match(argv[k]):
            out[-1] = f"{token}={argv[k]}"
            k += 1
    return out


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(negative_values(parser, sys.argv[1:] if argv is None else list(argv)))
    try:
        args.run(args)
    except BrokenPipeError:
        # the reader (e.g. `| head`) has gone: stop quietly, as command-line tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except api.NothingToWrite as exc:
        print(f"rvte {args.command}: {exc}", file=sys.stderr)
        return 2
    except InputError as exc:
        print(f"rvte {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (OSError, RuntimeError) as exc:
        print(f"rvte {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


# -- measured against modelled: rvte compare, rvte calibrate -------------------------------------


def _compare(args):
    report = api.compare(
        args.design,
        args.data,
        args.errors,
        load=args.load,
        ratio=args.ratio,
        **_record_options(args),
        points=args.points,
        csv_path=args.csv,
        plot_path=args.plot,
    )
    _show(report, args.json, (("csv", args.csv), ("plot", args.plot)))


def _calibrate(args):
    bounds = dict(args.bounds or ())
    with ProgressBar("calibrate", unit="model") as bar:
        report = api.calibrate(
            args.design,
            args.data,
            args.fit,
            target=args.target,
            errors=args.errors,
            load=args.load,
            bounds=bounds,
            ratio=args.ratio,
            **_record_options(args),
            points=args.points,
            maxiter=args.maxiter,
            popsize=args.popsize,
            seed=args.seed,
            output=args.output,
            progress=bar,
        )
    _show(report, args.json, ())


def _record_options(args) -> dict:
    return {
        "columns": args.columns,
        "units": args.units,
        "counts_per_rev": args.counts_per_rev,
        "remove_orders": args.remove_orders,
        "remove_input_orders": args.remove_input_orders,
        "keep_orders": args.keep_orders,
    }


def _bound(text: str) -> tuple[str, tuple[float, float]]:
    """NAME=LOWER:UPPER of --bounds."""
    try:
        name, pair = text.split("=", 1)
        lower, upper = (float(x) for x in pair.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected NAME=LOWER:UPPER in N/m, e.g. R_ca=7.4e10:8.0e10"
        ) from None
    return name.strip(), (lower, upper)


def _record_arguments(
    p,
    ratio_help: str = "the reducer's ratio (default and only allowed value: the design's)",
    required: bool = False,
) -> None:
    """How a bench CSV is read: the options of `rvte measure`, `compare` and `calibrate`."""
    p.add_argument("--ratio", type=float, required=required, help=ratio_help)
    p.add_argument(
        "--columns",
        type=_names,
        metavar="IN,OUT[,TIME]",
        help="names of the input angle, output angle and (optional) time columns",
    )
    p.add_argument(
        "--units",
        choices=("deg", "rad", "counts"),
        help="unit of both angle columns (default: from their names' suffix)",
    )
    p.add_argument(
        "--counts-per-rev",
        type=_numbers,
        metavar="N[,N_OUT]",
        help="encoder counts per revolution, for counts (two: input, output)",
    )
    p.add_argument(
        "--remove-orders",
        type=_orders,
        default=(1,),
        metavar="K[,K...]",
        help="orders of the output rotation fitted and removed as bench runout (from "
        "a model curve too, where there is one; default 1; none: none)",
    )
    p.add_argument(
        "--remove-input-orders",
        type=_orders,
        default=(),
        metavar="K[,K...]",
        help="orders of the input rotation (cycles per input revolution) removed too (default none)",
    )
    p.add_argument(
        "--keep-orders",
        type=_orders,
        default=(),
        metavar="K[,K...]",
        help="output orders to keep after all (the reducer's own)",
    )


def add_model_data_commands(sub) -> None:
    """`rvte compare` and `rvte calibrate`: the model against measurements."""
    p = sub.add_parser(
        "compare",
        help="a bench record beside the model at the record's load: "
        "te_pp, RMS, correlation, difference by angle and order",
    )
    _reducer_arguments(p, "resisting output torque [N*m] the bench ran at (0: no-load limit)")
    p.add_argument(
        "data", help="bench CSV, as for rvte measure (time_s, theta_in_deg, theta_out_deg or _rad, _counts)"
    )
    _record_arguments(p)
    p.add_argument(
        "--points",
        type=int,
        help="model points per output revolution (default "
        "8*z_p*z_c), interpolated to the record's input angles",
    )
    p.add_argument("--csv", help="write theta_in_rad,te_measured_arcsec,te_model_arcsec,difference_arcsec")
    p.add_argument("--plot", help="write a figure of both curves, the difference and the spectra")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=_compare)

    p = sub.add_parser(
        "calibrate",
        help="identify stiffnesses and friction of a design from "
        "measured TE peaks, curves or catalogue figures (least squares)",
    )
    _reducer_arguments(p, "resisting output torque [N*m] of the bench CSVs (a data-set TOML gives its own)")
    p.add_argument(
        "data",
        nargs="+",
        help="bench CSVs, data-set TOMLs ([[dataset]] with "
        "te_pp_arcsec or data, load_Nm, errors) or a catalogue TOML "
        "(torsional_rigidity_Nm_per_arcmin, lost_motion_arcmin, rated_torque_Nm, "
        "[[efficiency]], [[running_torque]])",
    )
    p.add_argument(
        "--fit",
        type=_names,
        required=True,
        metavar="NAME[,NAME...]",
        help="R_ca, R_b, R_pd (seed 003), stiffness fields (e.g. pin_disc_stiffness), "
        "output_stiffness, modification_scale or friction fields (e.g. mesh_friction)",
    )
    p.add_argument(
        "--target",
        choices=("peaks", "curve", "catalogue"),
        help="what is matched (default: what the data bring)",
    )
    p.add_argument(
        "--bounds",
        type=_bound,
        action="append",
        metavar="NAME=LOWER:UPPER",
        help="bounds of a fitted value in its unit (N/m for a stiffness; default: its "
        "start /4 to x4); repeat for each",
    )
    _record_arguments(p)
    p.add_argument(
        "--points",
        type=int,
        help="model points per output revolution (default "
        "32*z_p: under load the peaks within ~1 %% of the fully resolved model's)",
    )
    p.add_argument("--maxiter", type=int, help="differential_evolution generations (default 30)")
    p.add_argument("--popsize", type=int, help="differential_evolution members per fitted value (default 10)")
    p.add_argument("--seed", type=int, help="seed of differential_evolution (default 3)")
    p.add_argument(
        "-o", "--output", help="write the calibrated design TOML (for rvte te, rvte fmu build, the studies)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=_calibrate)


if __name__ == "__main__":
    sys.exit(main())
