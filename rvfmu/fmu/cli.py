"""`rvte fmu build` and `rvte fmu info`: a few lines each over `rvfmu.fmu.api`."""

from __future__ import annotations


def add_fmu_commands(subparsers) -> None:
    """Add the FMU sub-commands to the `rvte` sub-parsers."""
    fmu = subparsers.add_parser("fmu", help="build or inspect the reducer FMU (FMI 2.0 or 3.0 co-simulation)")
    sub = fmu.add_subparsers(dest="fmu_command", required=True)

    p = sub.add_parser("build", help="build an FMU from a design and an error set")
    p.add_argument("design", help="preset name or design TOML file")
    p.add_argument("--errors", help="error TOML file (default: no errors)")
    p.add_argument(
        "-o",
        "--output",
        default="RVReducer.fmu",
        help="FMU file to write, ending in .fmu (an existing file is replaced)",
    )
    p.add_argument("--points", type=int, help="TE map points per output revolution (default 8*z_p*z_c)")
    p.add_argument(
        "--native",
        action="store_true",
        help="compiled C that needs no Python: the quasi-static model, no parameters",
    )
    p.add_argument(
        "--fmi-version",
        default="2",
        metavar="{2,3}",
        help="the FMI standard of the FMU: 2 (default) or 3 (FMI 3.0, --native only)",
    )
    p.set_defaults(run=_build)

    p = sub.add_parser("info", help="print an FMU's FMI version and variables")
    p.add_argument("fmu", help="FMU file")
    p.set_defaults(run=_info)


def _build(args):
    from ..progress import ProgressBar
    from .api import fmu_build

    with ProgressBar("TE map") as bar:
        path = fmu_build(
            args.design,
            args.errors,
            args.output,
            points=args.points,
            progress=bar,
            native=args.native,
            fmi_version=args.fmi_version,
        )
    print(f"wrote {path}")
    if args.native:
        from .native import binaries_note

        print(binaries_note(path))


def _info(args):
    from .api import fmu_info

    print(fmu_info(args.fmu))
