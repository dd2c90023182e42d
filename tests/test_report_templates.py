"""`rvte report` through its Jinja2 templates: escaped HTML, sourced cells, templates found anywhere.

A Monte Carlo-only toy study (the linear RV-40E-121 at 64 points, 16 reducers, one
spec limit) whose name carries markup is run once; its 64 points alias the pin-passing
order, so its mc_summary.json has the aliasing check, whose cells test_report_html.py
does not look for.  The full report (Sobol, allocation, browser) is tested there.
"""

import json
import os
import subprocess
import sys
import time
import tomllib
from html.parser import HTMLParser
from pathlib import Path

import pytest
from tolerance_toy import write_study

import tolerance
from tolerance import report, run_mc
from tolerance.html_report import render_html, render_markdown
from tolerance.report_content import Code, Figure, Num, Para, Section, Table

ROOT = Path(__file__).resolve().parent.parent
NAME = "<script>alert(1)</script> & R&D"
TEMPLATES = Path(tolerance.__file__).parent / "templates"


class Page(HTMLParser):
    """Every start tag (tag, attrs), the text of <title> and <h1>, and every <td> as
    (attrs, text)."""

    def __init__(self, text):
        super().__init__()
        self.tags, self.cells, self.texts = [], [], {}
        self._open = None
        self.feed(text)
        self.close()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if tag in ("td", "title", "h1", "pre", "p"):
            self._open = [tag, attrs, ""]

    def handle_endtag(self, tag):
        if self._open is not None and tag == self._open[0]:
            if tag == "td":
                self.cells.append((self._open[1], self._open[2]))
            else:
                self.texts.setdefault(tag, []).append(self._open[2])
            self._open = None

    def handle_data(self, data):
        if self._open is not None:
            self._open[2] += data


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("templates")
    path = write_study(
        folder, study={"name": NAME, "metrics": ["te_pp"]}, spec={"te_pp_arcsec": 25.0}, montecarlo={"n": 16}
    )
    run_mc(path, plots=False)
    return report(folder / "toy" / "output", study_file=path)


def test_markup_in_a_study_name_is_escaped_in_the_html_and_kept_in_the_markdown(written):
    text = written.html.read_text()
    page = Page(text)
    assert "<script" not in text.lower()
    assert [tag for tag, _ in page.tags if tag == "script"] == []
    escaped = "&lt;script&gt;alert(1)&lt;/script&gt; &amp; R&amp;D"
    assert text.count(escaped) >= 3  # <title>, <h1>, the study row of the hashes
    assert page.texts["title"] == [f"Tolerance study {NAME!r}"]
    assert page.texts["h1"] == [f"Tolerance study {NAME!r}"]
    assert ("study", NAME) in [(a[1], b[1]) for a, b in zip(page.cells, page.cells[1:])]
    # The Markdown is Markdown: the name as written, nothing HTML-escaped.
    markdown = written.markdown.read_text()
    assert markdown.startswith(f"# Tolerance study {NAME!r}\n")
    assert "&lt;" not in markdown and "&amp;" not in markdown and "&#" not in markdown


def test_every_kind_of_block_escapes_its_text_and_keeps_its_source_attributes():
    evil = "<script>alert(1)</script> & \"quoted\" 'single'"
    key = ("metrics", evil, 0)
    section = Section(
        "s",
        f"section {evil}",
        [
            Para(f"para {evil}"),
            Para(f"note {evil}", "note"),
            Para(f"head {evil}", "h3"),
            Para(f"box {evil}", "warn"),
            Table(("name", "value"), [(evil, Num(0.123456, ".3f", 100, "x.json", key))], f"caption {evil}"),
            Code(f"code {evil}", f"{evil}\n"),
            Figure(b"\x89PNG\r\n\x1a\n", f"figure {evil}"),
        ],
    )
    clock = time.perf_counter()
    text = render_html(f"title {evil}", f"subtitle {evil}", (("bad", f"banner {evil}"),), [], [section])
    assert time.perf_counter() - clock < 2.0
    page = Page(text)
    assert "<script" not in text.lower() and [t for t, _ in page.tags if t == "script"] == []
    # title, h1, subtitle, banner, contents link, h2, 4 paragraphs, caption, name cell,
    # data-key, code title, code text, figure alt and caption: every place, escaped
    assert text.count("&lt;script&gt;alert(1)&lt;/script&gt; &amp; ") == 17
    assert page.texts["pre"] == [f"{evil}\n"]  # the code block exactly, once unescaped
    assert [attrs["alt"] for tag, attrs in page.tags if tag == "img"] == [f"figure {evil}"]
    (_, shown), (number, value) = page.cells
    assert shown == evil and value == "12.346"
    assert number == {
        "class": "num",
        "data-src": "x.json",
        "data-key": json.dumps(list(key)),
        "data-scale": "100",
    }
    assert json.loads(number["data-key"]) == list(key)
    # Markdown: the same texts, raw; a table cell's '|' escaped.
    markdown = render_markdown(
        "t", "s", (), [], [Section("s", "S", [Table(("a", "b"), [("x | y", Num(2.5))])]), section]
    )
    assert "| x \\| y | 2.5 |" in markdown and f"> {'box ' + evil}" in markdown
    assert f"```toml\n{evil}\n```" in markdown and "&lt;" not in markdown


PERCENT = {"fraction", "low", "high", "max_relative_change", "yield_at_risk"}


def test_the_cells_name_their_json_values_exactly_aliasing_check_included(written):
    out = written.html.parent
    summary = json.loads((out / "mc_summary.json").read_text())
    sourced = [(attrs, text) for attrs, text in Page(written.html.read_text()).cells if "data-src" in attrs]
    seen = set()
    for attrs, text in sourced:
        assert attrs["data-src"] == "mc_summary.json" and attrs["class"] == "num"
        key = json.loads(attrs["data-key"])
        value = summary
        for k in key:
            value = value[k]
        # data-scale is there exactly for the percentages, and the cell shows value × scale
        # in the digits of its format: passed and n as integers, percentages to 0.01, else 4 digits
        percent = bool(PERCENT & set(map(str, key)))
        assert attrs.get("data-scale") == ("100" if percent else None), key
        expected = (
            str(int(value))
            if key[-1] in ("passed", "n")
            else format(100 * value, ".2f")
            if key[:2] in (["aliasing", "max_relative_change"], ["aliasing", "yield_at_risk"])
            or key[0] == "yields"
            else format(value, ".3g")
            if key[:2] == ["aliasing", "max_change"]
            else format(value, ".4g")
        )
        assert text == expected, (key, text, value)
        seen.add(tuple(key))
    alias = summary["aliasing"]
    assert alias["columns"] == ["te_pp_arcsec"] and alias["yield_at_risk"]
    for column in alias["columns"]:
        assert ("aliasing", "max_change", column) in seen
        assert ("aliasing", "max_relative_change", column) in seen
    for label in alias["yield_at_risk"]:  # a JSON key with '<' in it, escaped and back
        assert "<" in label and ("aliasing", "yield_at_risk", label) in seen
    assert ("yields", 0, "fraction") in seen and ("metrics", "te_pp_arcsec", "mean") in seen


def test_the_templates_are_found_from_another_folder_and_are_package_data(tmp_path):
    script = (
        "from tolerance.html_report import render_html, render_markdown, _environment\n"
        "from tolerance.report_content import Para, Section\n"
        "parts = ('T & <b>', 'S', (('ok', 'Up to date: yes'),), [], "
        "[Section('x', 'X', [Para('p')])])\n"
        "print(_environment().get_template('report.html.j2').filename)\n"
        "print(render_html(*parts))\nprint(render_markdown(*parts))\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, "-c", script],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 0, run.stderr
    filename, _, rest = run.stdout.partition("\n")
    assert Path(filename) == TEMPLATES / "report.html.j2"
    assert rest.startswith("<!DOCTYPE html>\n") and "<title>T &amp; &lt;b&gt;</title>" in rest
    assert "# T & <b>\n\nS\n\n> **Up to date.** yes\n\n## X\n\np\n" in rest
    # Every template file is package data, so that an installed (non-editable) rvte has them.
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "jinja2>=3.1" in project["project"]["dependencies"]
    patterns = project["tool"]["setuptools"]["package-data"]["tolerance"]
    files = sorted(p.name for p in TEMPLATES.iterdir() if p.is_file())
    assert files == ["report.html.j2", "report.md.j2"]
    assert all(any(Path("templates", f).match(p) for p in patterns) for f in files)
