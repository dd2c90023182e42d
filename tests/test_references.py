"""Every file the README, the docs and the `--help` texts send a reader to exists."""

import argparse
import re

import pytest
from conftest import ROOT

from rvfmu import cli

TOP = ("rvfmu", "tolerance", "studies", "tests", "docs", ".ci")
# A path into the repository: a top-level folder, then names; or a Markdown file by name.
PATH = re.compile(
    r"(?<![\w./-])((?:%s)/[\w./-]*[\w-]|[\w-]+\.md)(?![\w/-])" % "|".join(re.escape(t) for t in TOP)
)
GENERATED = ("/output", "rvte_")  # folders a run writes; temporary names


def help_texts():
    """The --help text of `rvte` and of every sub-command, recursively."""
    texts = []

    def walk(parser):
        texts.append(parser.format_help())
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in action.choices.values():
                    walk(sub)

    walk(cli.build_parser())
    return texts


def documents():
    files = [
        ROOT / "README.md",
        *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "studies").rglob("README.md")),
    ]
    return {str(f.relative_to(ROOT)): f.read_text() for f in files}


def mentioned(text):
    paths = set()
    for match in PATH.finditer(text):
        path = match.group(1).rstrip(".")
        if not any(mark in path for mark in GENERATED):
            paths.add(path)
    return paths


def exists(path, source):
    here = (ROOT / source).parent if source else ROOT
    candidates = [ROOT / path, here / path]
    if path.endswith(".md") and "/" not in path:  # a Markdown file named alone: docs or beside
        candidates.append(ROOT / "docs" / path)
    return any(c.exists() for c in candidates)


def test_the_docs_exist_and_are_found_by_the_scan():
    docs = documents()
    assert "docs/model.md" in docs and "docs/studies.md" in docs
    assert "docs/model.md" in mentioned(docs["README.md"])
    assert "docs/studies.md" in mentioned(docs["README.md"])
    assert mentioned("see tolerance/README_SECTION.md and docs/x.md.") == {
        "tolerance/README_SECTION.md",
        "docs/x.md",
    }


@pytest.mark.parametrize("source", sorted(documents()))
def test_every_path_a_document_mentions_exists(source):
    missing = sorted(p for p in mentioned(documents()[source]) if not exists(p, source))
    assert not missing, f"{source} mentions files that do not exist: {missing}"


def test_every_path_a_help_text_mentions_exists():
    texts = help_texts()
    assert len(texts) > 8  # rvte, te, presets, ..., fmu build, mc, sobol
    found = set().union(*(mentioned(t) for t in texts))
    assert "docs/studies.md" in found and "docs/model.md" in found
    missing = sorted(p for p in found if not exists(p, ""))
    assert not missing, f"--help texts mention files that do not exist: {missing}"
