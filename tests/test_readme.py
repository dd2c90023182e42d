"""The README is short, starts with the two commands `.ci/run` runs, and its FMU example runs."""

import os
import re
import shlex
import subprocess
import sys

from conftest import ROOT

README = ROOT / "README.md"
MAX_LINES = 250  # a few screens: everything else lives in docs/


def readme():
    return README.read_text()


def section(text, title_start):
    """The text of the `## ` section whose title starts with `title_start`, up to the next one."""
    parts = re.split(r"^## ", text, flags=re.M)
    found = [p for p in parts[1:] if p.startswith(title_start)]
    assert len(found) == 1, f"README.md: expected one section starting '## {title_start}', got {len(found)}"
    return found[0]


def blocks(text, language):
    """The fenced code blocks of `language` in `text`, in order, without their fences."""
    return re.findall(r"^```%s\n(.*?)^```" % re.escape(language), text, flags=re.M | re.S)


def test_readme_is_at_most_250_lines():
    count = len(readme().splitlines())
    assert count <= MAX_LINES, f"README.md has {count} lines, at most {MAX_LINES} allowed"


def test_readme_starts_with_the_two_commands_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    # .ci/run's last two lines are the README's two commands, run as they are written
    commands = ci[-2:]
    assert commands[0].startswith("python3 -m venv .venv") and "pytest" in commands[1]
    lines = readme().splitlines()
    assert lines[0] == "# rvte — transmission error of RV reducers"
    assert lines[1] == ""
    assert lines[2:6] == ["```bash", commands[0], commands[1], "```"]


def test_readme_timings_keep_the_anchor_and_a_time_for_each_command():
    text = readme()
    assert "[Timings](#timings)" in text and "\n## Timings\n" in text
    timings = section(text, "Timings")
    duration = r"\| (\d+ min \d+ s|\d+(\.\d+)? s) \|"
    for what in ("rvte te RV-40E-121", "rvte mc studies/quick_mc.toml", "the test suite", ".ci/run"):
        rows = [line for line in timings.splitlines() if what in line]
        assert rows and re.search(duration, rows[0]), f"README Timings has no time for {what!r}"


def test_readme_links_to_every_doc_and_the_docs_exist():
    text = readme()
    linked = set(re.findall(r"\]\(([^)#]+)\)", text))
    for name in (
        "docs/model.md",
        "docs/studies.md",
        "docs/fmu.md",
        "docs/presets.md",
        "docs/benchmarks.md",
        "docs/bench-data.md",
        "docs/getting-started.md",
        "docs/running-studies.md",
        "docs/dynamic.md",
        "docs/efficiency.md",
        "CHANGELOG.md",
    ):
        assert name in linked, f"README.md does not link {name}"
    missing = sorted(p for p in linked if "://" not in p and not (ROOT / p).exists())
    assert not missing, f"README.md links files that do not exist: {missing}"


def test_readme_fmu_builds_write_different_files():
    fmu = section(readme(), "The reducer as an FMU")
    builds = [
        line
        for block in blocks(fmu, "bash")
        for line in block.splitlines()
        if line.startswith("rvte fmu build")
    ]
    outputs = [shlex.split(line.split("#")[0])[-1] for line in builds]
    assert len(builds) == 2 and len(set(outputs)) == 2, builds


def test_readme_fmpy_example_runs_as_written(tmp_path):
    fmu = section(readme(), "The reducer as an FMU")
    build = next(
        line
        for block in blocks(fmu, "bash")
        for line in block.splitlines()
        if line.startswith("rvte fmu build") and "--native" in line
    )
    (example,) = blocks(fmu, "python")
    # The README's paths are relative to the repository; run in a fresh folder so nothing
    # is written into the working tree, with the repository's input files given in full.
    args = [str(ROOT / a) if a.startswith("studies/") else a for a in shlex.split(build)[1:]]
    proc = subprocess.run(
        [sys.executable, "-m", "rvfmu.cli", *args], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    name = args[args.index("-o") + 1]
    assert (tmp_path / name).stat().st_size > 10_000
    assert f'simulate_fmu("{name}"' in example  # the example simulates what was built

    script = tmp_path / "example.py"
    script.write_text(example)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=120, env=env
    )
    assert run.returncode == 0, run.stderr
    match = re.fullmatch(r"te_pp (\d+\.\d) arcsec over (\d+) output rows\n", run.stdout)
    assert match, run.stdout
    assert int(match.group(2)) == 1001  # 1 s at 1 ms, both ends
    assert float(match.group(1)) > 0.0  # the errors and the load make a TE
