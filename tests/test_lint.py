"""The tree is lint-clean and formatted under pyproject.toml's [tool.ruff] settings (ruff is in
the `test` extra, so CI's pytest run checks both: `ruff check .` and `ruff format --check .`),
and those settings are the ones ruff applies."""

import re
import subprocess
import sys
import tomllib

from conftest import ROOT

TIME_LIMIT = 120.0  # s: a hung ruff fails here (it takes about a second on the tree)
LINE_LENGTH = 110  # pyproject.toml [tool.ruff] line-length


def ruff(*args, stdin=None):
    """ruff run from the repository root (so pyproject.toml configures it); its completed process."""
    return subprocess.run(
        [sys.executable, "-m", "ruff", *args, "--no-cache"],
        cwd=ROOT,
        input=stdin,
        capture_output=True,
        text=True,
        check=False,
        timeout=TIME_LIMIT,
    )


def codes(output):
    """The rule codes of ruff check's concise output, sorted."""
    return sorted(re.findall(r":\d+:\d+: ([A-Z]+\d+) ", output))


def test_ruff_check_finds_nothing():
    done = ruff("check", "--output-format", "concise", ".")
    assert done.returncode == 0, f"ruff check . found:\n{done.stdout}{done.stderr}"
    assert done.stdout.strip() == "All checks passed!", done.stdout


def test_ruff_format_check_finds_nothing():
    done = ruff("format", "--check", ".")
    assert done.returncode == 0, f"ruff format --check . would reformat:\n{done.stdout}{done.stderr}"


def test_the_core_imports_read_in_the_rooms_order():
    """isort (I001): a room's module imports the rooms before it in their order, its own last."""
    uses = '\n__all__ = ["InputError", "solve"]\n'
    source = "from .solver import solve\nfrom ..base.checks import InputError\n" + uses
    done = ruff(
        "check",
        "--output-format",
        "concise",
        "--stdin-filename",
        "rvfmu/core/statics/probe.py",
        "-",
        stdin=source,
    )
    assert done.returncode == 1 and codes(done.stdout) == ["I001"], done.stdout
    fixed = ruff("check", "--fix-only", "--stdin-filename", "rvfmu/core/statics/probe.py", "-", stdin=source)
    assert fixed.stdout == "from ..base.checks import InputError\nfrom .solver import solve\n" + uses, (
        fixed.stdout
    )


def test_the_selected_rules_catch_defects_in_the_package():
    source = (
        "import os\n\n\n"
        "def append(x, into=[]):\n"  # B006: one list shared by all calls
        "    into.append(x)\n"
        "    return into\n\n\n"
        "def total(rows):\n"
        "    for k in range(3):\n"  # B007: k never used
        "        rows = rows + 1\n"
        "    return rows + undefined\n"
    )  # F821
    done = ruff(
        "check", "--output-format", "concise", "--stdin-filename", "rvfmu/probe.py", "-", stdin=source
    )
    assert done.returncode == 1, done.stdout + done.stderr
    assert codes(done.stdout) == ["B006", "B007", "F401", "F821"], done.stdout


def test_fixtures_imported_by_tests_are_not_redefinitions_but_elsewhere_are():
    source = "from conftest import rv40  # noqa: F401 - a fixture\n\n\ndef test_it(rv40):\n    assert rv40\n"
    in_tests = ruff(
        "check", "--output-format", "concise", "--stdin-filename", "tests/test_probe.py", "-", stdin=source
    )
    assert in_tests.returncode == 0, in_tests.stdout + in_tests.stderr
    elsewhere = ruff(
        "check", "--output-format", "concise", "--stdin-filename", "rvfmu/probe.py", "-", stdin=source
    )
    assert elsewhere.returncode == 1 and codes(elsewhere.stdout) == ["F811"], elsewhere.stdout


def test_the_formatter_wraps_at_the_configured_line_length():
    head, tail = "result = function(", ", second_argument)\n"

    def call(width):
        """A formatted one-line call exactly `width` columns wide; its first argument."""
        name = "a" * (width - len(head) - len(tail) + 1)
        assert len(head + name + tail) - 1 == width
        return head + name + tail, name

    line, _ = call(LINE_LENGTH)
    fits = ruff("format", "--stdin-filename", "rvfmu/probe.py", "-", stdin=line)
    assert fits.returncode == 0 and fits.stdout == line, fits.stdout + fits.stderr
    line, name = call(LINE_LENGTH + 1)
    wrapped = ruff("format", "--stdin-filename", "rvfmu/probe.py", "-", stdin=line)
    assert wrapped.returncode == 0, wrapped.stderr
    assert wrapped.stdout == f"{head}\n    {name}, second_argument\n)\n", wrapped.stdout
    # double quotes: the formatter's setting, which the code already follows
    quoted = ruff("format", "--stdin-filename", "rvfmu/probe.py", "-", stdin="name = 'rvte'\n")
    assert quoted.stdout == 'name = "rvte"\n', quoted.stdout


def test_ruff_comes_with_the_test_extra_ci_installs():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    ruff_specs = [spec for spec in extras["test"] if re.match(r"ruff\b", spec)]
    # 0.17: the version whose formatting and rules the tree was measured with
    assert ruff_specs == ["ruff>=0.17"], extras["test"]
