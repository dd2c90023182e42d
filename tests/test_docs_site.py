"""The documentation site (mkdocs.yml, docs/) builds with `mkdocs build --strict`, and a broken
link or a public function of the API pages without a docstring fails that build."""

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import time
import tomllib

import yaml
from conftest import ROOT

BUILD_SECONDS = 60  # about 7 s alone on the 2-core machine; room for a busy one
PACKAGES = ("rvfmu", "tolerance")


def build(config_dir, site):
    """Run `mkdocs build --strict` on config_dir/mkdocs.yml into `site`; the finished process,
    its log and errors in .stdout."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}  # keep the theme's banner out of stderr
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "-f",
            str(config_dir / "mkdocs.yml"),
            "-d",
            str(site),
        ],
        cwd=config_dir,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=300,
        env=env,
    )


def site_copy(tmp_path):
    """mkdocs.yml and docs/ copied into tmp_path/src, the packages linked next to them (the
    mkdocstrings `paths` are relative to mkdocs.yml)."""
    src = tmp_path / "src"
    src.mkdir()
    shutil.copy(ROOT / "mkdocs.yml", src)
    shutil.copytree(ROOT / "docs", src / "docs", ignore=shutil.ignore_patterns("__pycache__"))
    for package in PACKAGES:
        (src / package).symlink_to(ROOT / package, target_is_directory=True)
    return src


def hooks_module():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def nav_files(nav):
    """The page files of an mkdocs nav (nested lists of {title: file or list})."""
    for item in nav:
        for value in item.values() if isinstance(item, dict) else [item]:
            if isinstance(value, list):
                yield from nav_files(value)
            else:
                yield value


UNDOCUMENTED_PACKAGE = {
    "__init__.py": '"""A package for the docstring check."""\n'
    "from .inner import exported, Exported\n"
    '__all__ = ["documented", "bare", "Thing", "exported", "Exported"]\n\n\n'
    'def documented():\n    """Has one."""\n\n\n'
    "def bare():\n    return 1\n\n\n"
    "def not_exported():\n    return 2\n\n\n"
    "def _private():\n    return 3\n\n\n"
    'class Thing:\n    """Has one."""\n\n'
    "    def method(self):\n        return 4\n\n"
    "    def _hidden(self):\n        return 5\n\n"
    '    def told(self):\n        """Has one."""\n',
    "inner.py": '"""Defines what the package exports."""\n\n\n'
    "def exported():\n    return 6\n\n\n"
    "class Exported:\n    pass\n",
}


def write_package(folder, name="undocumented_pkg"):
    (folder / name).mkdir()
    for file, text in UNDOCUMENTED_PACKAGE.items():
        (folder / name / file).write_text(text)
    return name


def test_the_site_builds_strict_with_every_page_and_the_api_reference(tmp_path):
    start = time.monotonic()
    proc = build(ROOT, tmp_path / "site")
    seconds = time.monotonic() - start
    assert proc.returncode == 0, proc.stdout[-3000:]
    assert seconds < BUILD_SECONDS, f"mkdocs build --strict took {seconds:.0f} s"

    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    pages = sorted(str(p.relative_to(ROOT / "docs")) for p in (ROOT / "docs").rglob("*.md"))
    assert sorted(nav_files(config["nav"])) == pages  # every page is in the nav, once
    for page in pages:
        assert (tmp_path / "site" / page.replace(".md", ".html")).is_file(), page

    # the API pages hold the functions and classes rendered from their docstrings
    for html, identifiers in {
        "api/rvfmu-api.html": (
            "rvfmu.api.te",
            "rvfmu.api.TEReport",
            "rvfmu.api.simulate",
            "rvfmu.api.calibrate",
        ),
        "api/fmu.html": (
            "rvfmu.fmu.api.fmu_build",
            "rvfmu.fmu.api.fmu_info",
            "rvfmu.fmu.native.build_native_fmu",
            "rvfmu.fmu.slave.RVReducer",
        ),
        "api/tolerance.html": (
            "tolerance.study.load_study",
            "tolerance.mc_runs.run_mc",
            "tolerance.sobol_runs.run_sobol",
            "tolerance.allocation.allocate",
            "tolerance.frames.load_results",
            "tolerance.backends.InProcess.map",
            "tolerance.html_report.report",
            "tolerance.html_report.StudyReport",
            "tolerance.report_content.gather",
            "tolerance.report_content.Freshness",
        ),
    }.items():
        text = (tmp_path / "site" / html).read_text()
        for identifier in identifiers:
            assert f'id="{identifier}"' in text, f"{html} does not document {identifier}"
    # file paths outside docs/ stay as text: the site has no link leaving it
    for html in (tmp_path / "site").rglob("*.html"):
        assert not re.search(r'href="(\.\./)+(README|CHANGELOG)\.md', html.read_text()), html


def test_a_broken_link_fails_the_strict_build_and_is_named(tmp_path):
    src = site_copy(tmp_path)
    page = src / "docs" / "getting-started.md"
    links = {
        "missing-page.md": "missing-page.md",  # a page that is not there
        "../README.md": "../README.md",  # a file outside docs/
        "model.md#no-such-section": "#no-such-section",
    }  # an anchor that is not there
    page.write_text(page.read_text() + "\n" + "\n".join(f"See [this]({link})." for link in links) + "\n")
    proc = build(src, tmp_path / "site")
    assert proc.returncode != 0
    assert "Aborted with 3 warnings in strict mode" in proc.stdout, proc.stdout[-3000:]
    for link, named in links.items():
        warning = [
            line for line in proc.stdout.splitlines() if "getting-started.md" in line and named in line
        ]
        assert len(warning) == 1, (link, proc.stdout[-3000:])


def test_a_public_function_without_docstring_fails_the_build_and_is_named(tmp_path):
    src = site_copy(tmp_path)
    name = write_package(src)
    page = src / "docs" / "api" / "tolerance.md"
    page.write_text(page.read_text() + f"\n::: {name}\n")
    proc = build(src, tmp_path / "site")
    assert proc.returncode != 0
    lines = [line for line in proc.stdout.splitlines() if "have no docstring" in line]
    assert len(lines) == 1, proc.stdout[-3000:]
    assert lines[0].endswith(
        f"4 public function(s)/class(es) of the API pages have no docstring "
        f"(docs/hooks.py): {name}.bare, {name}.Thing.method, "
        f"{name}.inner.exported, {name}.inner.Exported"
    ), lines[0]
    assert not (tmp_path / "site" / "index.html").exists()  # stopped before writing pages


def test_the_docstring_check_lists_exactly_the_undocumented_public_objects(tmp_path):
    hooks = hooks_module()
    name = write_package(tmp_path)
    # __all__ decides for the package; its exported names are checked where they are defined
    assert hooks.undocumented([name], [tmp_path]) == [
        f"{name}.bare",
        f"{name}.Thing.method",
        f"{name}.inner.exported",
        f"{name}.inner.Exported",
    ]
    # a module without __all__: every public name defined in it, none it imports
    assert hooks.undocumented([f"{name}.inner"], [tmp_path]) == [
        f"{name}.inner.exported",
        f"{name}.inner.Exported",
    ]
    assert hooks.undocumented([f"{name}.documented"], [tmp_path]) == []
    missing = f"{name}.no_such_thing"
    try:
        hooks.undocumented([missing], [tmp_path])
    except Exception as exc:  # mkdocs' PluginError: the build stops and names it
        assert type(exc).__name__ == "PluginError" and f"'::: {missing}'" in str(exc), exc
    else:
        raise AssertionError(f"{missing} was not refused")


def test_every_public_object_of_the_api_pages_has_a_docstring(tmp_path):
    hooks = hooks_module()
    identifiers = hooks.api_identifiers(ROOT / "docs")
    assert {
        "rvfmu.api",
        "rvfmu.fmu.api",
        "tolerance.run",
        "tolerance.study",
        "tolerance.html_report",
        "tolerance.report_content",
    } <= set(identifiers)
    assert hooks.undocumented(identifiers, [ROOT]) == []


def test_the_install_command_brings_the_docs_tools():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    names = {re.match(r"[A-Za-z0-9_.\[\]-]+", spec).group(0): spec for spec in extras["docs"]}
    for tool in ("mkdocs", "mkdocs-material", "mkdocstrings[python]"):
        assert tool in names and ">=" in names[tool], (tool, extras["docs"])
    first = (ROOT / ".ci" / "run").read_text().splitlines()[-2]
    assert 'pip install -e ".[test,docs]"' in first
