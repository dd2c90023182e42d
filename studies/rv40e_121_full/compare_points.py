"""The Sobol ranking at a study file's points per output revolution against 12 480 (8 z_p z_c).

12 480 points resolve the pin-passing order z_p * z_c = 1560 of the
RV-40E-121 with 8 points per period; a study file may use fewer (720 for the
rated file, 3200 for the no-load one) to save time.  This runs the Sobol job
of both study files of this folder at a small n as they are and with
`points = 12480` (a copy of each file beside its output), and prints, for the
same Saltelli rows, the indices at both resolutions side by side and how
te_pp itself moves.  Stored runs are reused (the study's own from the first
rows of its N = 1024 run).

    python studies/rv40e_121_full/compare_points.py [--n-no-load 16] [--n-rated 32] [--processes 2]

(n = 0 leaves that file out.)
"""

import argparse
import re
from pathlib import Path

import numpy as np

from tolerance import load_study, sobol
from tolerance.backends import make_backend
from tolerance.run import compute
from tolerance.sobol_runs import other_sobol_jobs, sobol_job

HERE = Path(__file__).resolve().parent
STUDIES = HERE.parent
FINE = 12480


def variant(study: Path, suffix: str, **values) -> Path:
    """A copy of the study file with these keys set (TOML values as text or numbers; None
    takes the key out), named <name>_<suffix>, its output in this folder's output/."""
    text = study.read_text()
    name = re.search(r'(?m)^name\s*=\s*"([^"]+)"', text).group(1) + f"_{suffix}"
    for key, value in (("name", f'"{name}"'), ("output", f'"{HERE / "output" / name}"'), *values.items()):
        line = f"# {key}: not in this copy" if value is None else f"{key} = {value}"
        text, count = re.subn(rf"(?m)^{key}\s*=.*$", line, text)
        assert count == 1, key
    path = HERE / "output" / f"{name}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def fine_copy(study: Path) -> Path:
    """The study file with points = 12480, its own name and output folder."""
    return variant(study, str(FINE), points=FINE)


class Job:
    """The Sobol job of a study file at n, through its store (batches reused or computed),
    analysed here: the output folder's own sobol_indices.json is left alone."""

    def __init__(self, path: Path, n: int, processes: int):
        self.study = load_study(path)
        problem = self.study.problem()
        self.X = sobol.sample(problem, n, False, seed=self.study.seed)
        self.Y = compute(
            self.study,
            sobol_job(n, False),
            self.X.shape[0],
            lambda s, e: self.X[s:e],
            make_backend(processes),
            prefix_jobs=other_sobol_jobs(problem, n, False),
        ).Y
        self.analyses = sobol.analyze(
            problem,
            self.Y,
            self.study.metric_columns,
            False,
            self.study.resamples,
            self.study.sobol_confidence,
            self.study.seed,
        )


def side_by_side(a: Job, b: Job, label_a: str, label_b: str, windup: bool) -> list:
    """Markdown lines: each metric of the same rows in runs a and b, the values and the
    indices side by side (the windup metrics only if `windup`)."""
    lines = []
    for j, column in enumerate(a.study.metric_columns):
        if not windup and not column.startswith("te_"):
            continue
        ya, yb = a.Y[:, j], b.Y[:, j]
        lines.append(
            f"`{column}`: {label_a} / {label_b}: mean ratio {np.mean(ya / yb):.3f}, "
            f"correlation {np.corrcoef(ya, yb)[0, 1]:.4f}, largest difference "
            f"{np.max(np.abs(ya - yb)):.2f} (mean {yb.mean():.1f} {label_b})"
        )
        lines.append("")
        ia, ib = a.analyses[column].indices, b.analyses[column].indices
        ra, rb = np.argsort(np.argsort(-ia.ST_reported)), np.argsort(np.argsort(-ib.ST_reported))
        lines.append(f"| factor | ST {label_a} | ST {label_b} | rank {label_a} | rank {label_b} |")
        lines.append("|---|---|---|---|---|")
        for g in np.argsort(-ib.ST_reported):
            lines.append(
                f"| `{ia.names[g]}` | {ia.ST_reported[g]:.3f} ± {ia.ST_conf[g]:.3f} | "
                f"{ib.ST_reported[g]:.3f} ± {ib.ST_conf[g]:.3f} | {ra[g] + 1} | {rb[g] + 1} |"
            )
        lines.append("")
        lines.append(
            f"largest |ST({label_a}) - ST({label_b})| over the factors: "
            f"{np.max(np.abs(ia.ST_reported - ib.ST_reported)):.3f}"
        )
        lines.append("")
    return lines


def compare(study: Path, n: int, processes: int) -> str:
    coarse = Job(study, n, processes)
    fine = Job(fine_copy(study), n, processes)
    assert np.array_equal(coarse.X, fine.X)
    lines = [
        f"### {study.name}: n = {n} ({coarse.X.shape[0]} reducers, the same rows at both resolutions)",
        "",
    ]
    lines += side_by_side(coarse, fine, f"at {coarse.study.points}", f"at {FINE}", windup=False)
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-no-load", type=int, default=16)
    parser.add_argument("--n-rated", type=int, default=32)
    parser.add_argument("--processes", type=int, default=2)
    args = parser.parse_args(argv)
    for name, n in (("rv40e_121_full.toml", args.n_no_load), ("rv40e_121_full_rated.toml", args.n_rated)):
        if n > 0:  # 0 leaves that file out
            print(compare(STUDIES / name, n, args.processes))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
