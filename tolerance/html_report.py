"""`rvte report OUTPUT_DIR`: a study's results in one HTML file to send, a Markdown summary to keep.

What the report shows (the numbers, their sources, the freshness banners, the
figures) is gathered by tolerance/report_content.py; this module writes it
through two Jinja2 templates in tolerance/templates/:

- report.html.j2, autoescaped: every text that comes from the study folder
  (a study name, a factor name, an error file) is HTML-escaped by Jinja, so a
  `<script>` in a study name is shown as text, never run.  The page is
  self-contained: inline CSS, figures as base64 PNG, no script and no link out
  of the file.  A number in a table names its source (data-src, data-key and,
  if it shows the value times a factor, data-scale), so a script can check the
  HTML against the JSON.
- report.md.j2, not escaped (Markdown is not HTML): the same sections as
  text and tables, without the figures.

Nothing in either depends on the time it was written: the same folder gives
the same bytes.
"""

from __future__ import annotations

import base64
import json
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import jinja2

from rvfmu.core.base.checks import InputError
from rvfmu.outputs import output_file

# The content's names stay importable from here, where `rvte report` always had them.
from .report_content import (
    FIGURE_DPI,
    MC_KEYS,
    ORDERS_SHOWN,
    S2_SHOWN,
    SOBOL_KEYS,
    Code,
    Content,
    Figure,
    Found,
    Freshness,
    Nominal,
    Num,
    Para,
    Section,
    Table,
    check_allocation,
    freshness,
    gather,
    job_fingerprints,
    nominal_reducer,
    package_versions,
    sobol_analyses,
    stored_study,
)
from .store import study_output_folder
from .study import load_study

__all__ = [
    "DEFAULT_HTML",
    "FIGURE_DPI",
    "MC_KEYS",
    "ORDERS_SHOWN",
    "S2_SHOWN",
    "SOBOL_KEYS",
    "Code",
    "Content",
    "Figure",
    "Found",
    "Freshness",
    "Nominal",
    "Num",
    "Para",
    "Section",
    "StudyReport",
    "Table",
    "check_allocation",
    "freshness",
    "gather",
    "job_fingerprints",
    "nominal_reducer",
    "package_versions",
    "render_html",
    "render_markdown",
    "report",
    "sobol_analyses",
    "stored_study",
]

DEFAULT_HTML = "report.html"
HTML_TEMPLATE = "report.html.j2"
MARKDOWN_TEMPLATE = "report.md.j2"


# -- the record ------------------------------------------------------------------------------


@dataclass(frozen=True)
class StudyReport:
    """What `report` wrote: the HTML and Markdown files and the key numbers (`summary`)."""

    html: Path
    markdown: Path
    summary: dict

    def to_json(self) -> dict:
        """What `rvte report --json` prints: the summary's key numbers with the paths of the
        HTML and Markdown files written."""
        return {**self.summary, "html": str(self.html), "markdown": str(self.markdown)}

    def text(self) -> str:
        """What `rvte report` prints: the study, its status and the two files written."""
        lines = [f"report of study {self.summary['study']!r}: {self.summary['status']}"]
        lines += [f"wrote html          {self.html}", f"wrote markdown      {self.markdown}"]
        return "\n".join(lines)


def report(output_dir, html_path=None, markdown_path=None, *, study_file=None) -> StudyReport:
    """Write the report of a study's output folder: one self-contained HTML file, a Markdown summary.

    html_path: default report.html in the output folder; markdown_path:
    default the HTML file's name with .md.  study_file: the study file as it
    is now, to tell whether it changed since the results were computed
    (default: NAME.toml beside NAME/output, where a study's output goes by
    default).  Every input and output path is checked before any work
    (InputError).  Returns the paths and the summary (`StudyReport.to_json`).
    """
    folder = study_output_folder(output_dir, "output_dir")
    html_path = output_file(
        "html", folder / DEFAULT_HTML if html_path is None else html_path, ("html", "htm")
    )
    markdown_path = output_file(
        "markdown", html_path.with_suffix(".md") if markdown_path is None else markdown_path, ("md",)
    )
    if markdown_path.resolve() == html_path.resolve():
        raise InputError("markdown", str(markdown_path), "must differ from the HTML file")
    current = None if study_file is None else load_study(study_file, output=folder)
    content = gather(folder, current, study_file is not None)
    parts = (content.title, content.subtitle, content.banners, content.head, content.sections)
    html_path.write_text(render_html(*parts))
    markdown_path.write_text(render_markdown(*parts))
    return StudyReport(html_path, markdown_path, content.summary)


# -- rendering -----------------------------------------------------------------------------------


def render_html(title: str, subtitle: str, banners, head, sections) -> str:
    """The HTML page (report.html.j2, autoescaped): banners [(level, text)] at the top, then
    the head sections (the key results) and the sections, each listed in the contents bar."""
    return (
        _environment()
        .get_template(HTML_TEMPLATE)
        .render(title=title, subtitle=subtitle, banners=banners, sections=[*head, *sections])
    )


def render_markdown(title: str, subtitle: str, banners, head, sections) -> str:
    """The same sections as Markdown (report.md.j2, not escaped): tables and texts, no figures."""
    text = (
        _environment()
        .get_template(MARKDOWN_TEMPLATE)
        .render(title=title, subtitle=subtitle, banners=banners, sections=[*head, *sections])
    )
    return text.rstrip() + "\n"


@cache
def _environment() -> jinja2.Environment:
    """The templates' environment, built once: templates from the package (found wherever the
    process runs), escaping on for .html.j2 only, an undefined name an error, not blank."""
    env = jinja2.Environment(
        loader=jinja2.PackageLoader("tolerance", "templates"),
        autoescape=jinja2.select_autoescape(
            enabled_extensions=("html", "html.j2"), default_for_string=True, default=False
        ),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.tests.update(
        num=lambda x: isinstance(x, Num),
        table=lambda x: isinstance(x, Table),
        para=lambda x: isinstance(x, Para),
        code=lambda x: isinstance(x, Code),
        figure=lambda x: isinstance(x, Figure),
        hashlike=_hashlike,
    )
    env.filters.update(
        base64=lambda data: base64.b64encode(data).decode(),
        json_path=lambda key: json.dumps(list(key)),
        md_cell=_markdown_cell,
    )
    return env


def _hashlike(cell) -> bool:
    """A sha256 in hex: set in a monospace cell that may break anywhere (td.hash)."""
    text = str(cell)
    return len(text) == 64 and all(c in "0123456789abcdef" for c in text)


def _markdown_cell(text: str) -> str:
    """A Markdown table cell: "|" escaped, on one line, never empty (an empty cell is a space)."""
    return text.replace("|", "\\|").replace("\n", " ") or " "
