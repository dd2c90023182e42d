"""`rvte mc`, `rvte sobol` and `rvte report`: registered on the `rvte` parser by
`add_study_commands`, which `rvte` finds through the entry-point group `rvte.commands`
(pyproject.toml).

Each sub-command is a few lines over `tolerance.run_mc` / `tolerance.run_sobol` /
`tolerance.report`.
The table goes to stdout, or with --json one JSON document (for scripts);
the progress bar, the load warning, the cost estimate and the one-line run
summary go to stderr.  Ctrl-C ends a run with one line on stderr, the number
of batches its output folder keeps for the next run, and exit code 130
(128 + SIGINT, the shell's convention); the backends end their workers.
"""

from __future__ import annotations

import functools
import json
import signal
import sys
import threading

INTERRUPTED = 128 + signal.SIGINT  # the exit code of a command ended by Ctrl-C


def _log(text):
    print(text, file=sys.stderr)


def _resumable(job_of):
    """A sub-command that ends on Ctrl-C with one line (not a traceback) and INTERRUPTED.

    job_of(args) -> the job whose batches the line counts (None: every batch of the
    output folder).  By the time the interrupt arrives here the backend has ended its
    workers; a second Ctrl-C is ignored while the batches are counted.
    """

    def wrap(command):
        @functools.wraps(command)
        def run(args):
            from .run import STOP

            if threading.current_thread() is not threading.main_thread():
                return command(args)  # signals reach the main thread only
            STOP.clear()
            handler, hook = signal.signal(signal.SIGINT, _interrupt), sys.unraisablehook
            sys.unraisablehook = _unraisable
            try:
                command(args)
            except KeyboardInterrupt:
                signal.signal(signal.SIGINT, signal.SIG_IGN)
                print(
                    f"interrupted: {_kept(args, job_of)} batches kept, run the same command to resume",
                    file=sys.stderr,
                )
                raise SystemExit(INTERRUPTED) from None
            finally:
                sys.unraisablehook = hook
            if handler is not None:  # None: a handler not set from Python, left as it is
                signal.signal(signal.SIGINT, handler)

        return run

    return wrap


def _interrupt(signum, frame):
    """Ctrl-C: a KeyboardInterrupt, and `run.STOP` in case Python swallows it."""
    from .run import STOP

    STOP.set()
    raise KeyboardInterrupt


def _unraisable(unraisable):
    """An interrupt that Python swallowed (in a __del__ or a garbage-collector callback) is
    not printed as a traceback: `run.STOP` stops the run at its next batch instead."""
    if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
        return
    sys.__unraisablehook__(unraisable)


def _kept(args, job_of) -> int:
    """Batch files kept in the output folder of the interrupted run (0 if none can be)."""
    from rvfmu.core.base.checks import InputError

    from .run import stored_batches

    try:
        return stored_batches(args.study, args.output, job_of(args))
    except (InputError, OSError):  # the study or its folder never got far enough to hold any
        return 0


def _sobol_job(args) -> str:
    from .run import _load
    from .sobol_runs import sobol_job
    from .study import sobol_base_samples

    study = _load(args.study, args.output)
    n = study.sobol_n if args.n is None else sobol_base_samples("n", args.n)
    return sobol_job(n, bool(args.second_order) or study.second_order)


@_resumable(lambda args: "mc")
def _mc(args):
    from .mc_runs import run_mc

    result = run_mc(
        args.study,
        args.n,
        output=args.output,
        processes=args.processes,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=None,
        plots=not args.no_plots,
        log=_log,
        yes=args.yes,
    )
    _show(result, args.json)


@_resumable(_sobol_job)
def _sobol(args):
    from .sobol_runs import run_sobol

    result = run_sobol(
        args.study,
        args.n,
        second_order=True if args.second_order else None,
        output=args.output,
        processes=args.processes,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=None,
        plots=not args.no_plots,
        log=_log,
        yes=args.yes,
        method=args.method,
        rounds=True if args.rounds else None,
    )
    _show(result, args.json)


def _report(args):
    from .html_report import report

    result = report(args.output_dir, args.output, args.markdown, study_file=args.study)
    for text in result.summary["warnings"]:
        _log(f"warning: {text}")
    print(json.dumps(result.to_json(), indent=1) if args.json else result.text())


@_resumable(lambda args: None)
def _allocate(args):
    from .allocation import allocate

    result = allocate(
        args.study,
        args.yield_target,
        output=args.output,
        progress=None,
        n=args.n,
        processes=args.processes,
        log=_log,
        yes=args.yes,
        looks=args.looks,
    )
    _show(result, args.json)


def _show(result, as_json):
    if as_json:
        print(json.dumps(result.to_json(), indent=1))
        return
    print(result.table())
    for label, path in result.files.items():
        print(f"wrote {label:<13} {path}")


def _common(p):
    p.add_argument("study", help="study TOML file (see docs/studies.md)")
    p.add_argument(
        "-o",
        "--output",
        help="output folder (default: the study's [study] output, "
        "or <study file name>/output beside the study file)",
    )
    where = p.add_mutually_exclusive_group()
    where.add_argument("--processes", type=int, metavar="N", help="evaluate on N local worker processes")
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="evaluate on a Dask LocalCluster of N single-threaded workers",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="evaluate on the Dask cluster at ADDRESS (tcp://host:port)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON document instead of the table")
    p.add_argument("--no-plots", action="store_true", help="write no figures")
    p.add_argument(
        "--yes",
        action="store_true",
        help="run even if the estimate (printed before "
        "the run, from its first batch) is above a day or above the free disk",
    )


def add_study_commands(subparsers) -> None:
    """Add the tolerance-study sub-commands to the `rvte` sub-parsers."""
    p = subparsers.add_parser(
        "mc", help="Monte Carlo of a tolerance study: TE distribution, yield against the spec"
    )
    _common(p)
    p.add_argument("-n", type=int, help="reducers to sample (default: the study's [montecarlo] n)")
    p.set_defaults(run=_mc)

    p = subparsers.add_parser("sobol", help="Sobol ranking of the tolerances of a study")
    _common(p)
    p.add_argument(
        "-n",
        type=int,
        help="base samples, a power of 2 (default: the study's "
        "[sobol] n); the model runs n*(G+2) times for G Sobol groups",
    )
    p.add_argument("--second-order", action="store_true", help="also second-order indices (n*(2G+2) runs)")
    p.add_argument(
        "--method",
        help="saltelli (every reducer of the design solved, the "
        "reference) or linearized (the TE curve linearized in the errors: 2A+1 "
        "solves for A error components, checked on solved reducers; for loaded "
        "studies); default: the study's [sobol] method, else saltelli",
    )
    p.add_argument(
        "--rounds",
        action="store_true",
        help="stop by itself: double the base "
        "samples (the linearized method's solved ones) from 64 until every metric's "
        "order groups are those of the two rounds before, n at most (default: the study's "
        "[sobol] rounds)",
    )
    p.set_defaults(run=_sobol)

    p = subparsers.add_parser(
        "report",
        help="one self-contained HTML report (and a Markdown "
        "summary) of a study's output folder, to send or to keep",
    )
    p.add_argument("output_dir", help="the study's output folder (written by rvte mc / rvte sobol)")
    p.add_argument(
        "-o",
        "--output",
        metavar="HTML",
        help="the HTML file to write (default: report.html in the output folder)",
    )
    p.add_argument(
        "--markdown",
        metavar="MD",
        help="the Markdown summary to write (default: the HTML file's name with .md)",
    )
    p.add_argument(
        "--study",
        metavar="STUDY",
        help="the study file as it is now, to tell whether "
        "it changed since the results were computed (default: NAME.toml beside "
        "NAME/output, the default output folder of a study)",
    )
    p.add_argument("--json", action="store_true", help="print the summary as one JSON document")
    p.set_defaults(run=_report)

    p = subparsers.add_parser(
        "allocate",
        help="least-cost tolerances of a study for a yield "
        "target, verified by Monte Carlo (see docs/studies.md)",
    )
    p.add_argument("study", help="study TOML file with a [spec] (costs: [tolerances.NAME.cost])")
    p.add_argument(
        "--yield",
        dest="yield_target",
        type=float,
        default=0.9973,
        metavar="Y",
        help="yield to reach against all spec lines at once (default 0.9973)",
    )
    p.add_argument(
        "-n",
        type=int,
        help="reducers of each verification Monte Carlo at most (default: the "
        "study's [montecarlo] n, at least 10000 for a yield >= 0.99)",
    )
    p.add_argument(
        "--looks",
        type=int,
        metavar="K",
        help="each verification looks at its yield after n/16, n/8, ... n reducers "
        "(K looks at most, none below 500) and stops once it is clear of the target "
        "(default 5; 1: one Monte Carlo of n reducers)",
    )
    p.add_argument(
        "-o",
        "--output",
        help="output folder, this study's or new (default: the "
        "study's); gets <name>_allocated.toml and allocation.json",
    )
    p.add_argument(
        "--processes",
        type=int,
        metavar="N",
        help="run the training and the Monte Carlo verifications on N local worker processes",
    )
    p.add_argument("--json", action="store_true", help="print allocation.json instead of the table")
    p.add_argument(
        "--yes",
        action="store_true",
        help="run even if a Monte Carlo's estimate is above a day or above the free disk",
    )
    p.set_defaults(run=_allocate)
