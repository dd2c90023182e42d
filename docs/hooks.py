"""MkDocs hook: the build fails when a public function or class of the API pages has no docstring.

mkdocstrings renders what has a docstring and silently leaves out what has none
(`show_if_no_docstring: false` in mkdocs.yml), so a new public function without
one would vanish from the reference without a word.  Before the build, this
hook reads the `::: identifier` lines of the pages under `docs/api/`, loads
those objects with griffe (statically, as mkdocstrings does, nothing is
imported) and lists every public function, class and method among them that
has no docstring.  Public: no leading underscore and, for a module that
defines `__all__`, named in it (its names imported from elsewhere are checked
where they are defined).  A non-empty list stops the build (`PluginError`),
with or without --strict.
"""

from __future__ import annotations

import re
from pathlib import Path

import griffe
from mkdocs.exceptions import PluginError

API_DIR = "api"  # under docs_dir
IDENTIFIER = re.compile(r"^:::\s+([\w.]+)\s*$", re.M)


def api_identifiers(docs_dir) -> list[str]:
    """The identifiers of the `::: identifier` lines of docs_dir/api/*.md, in page order."""
    found = []
    for page in sorted((Path(docs_dir) / API_DIR).glob("*.md")):
        found += [name for name in IDENTIFIER.findall(page.read_text()) if name not in found]
    return found


def _public_members(obj):
    """The public members of a module or class: the names of `__all__` in its order where it
    exists (aliases followed to their target), else the non-underscore names defined in it."""
    if obj.is_module and obj.exports is not None:
        names = [str(name) for name in obj.exports]  # griffe gives names or expressions
        for name in dict.fromkeys(names):
            member = obj.members.get(name)
            if member is not None and member.is_alias:
                try:
                    member = member.final_target
                except griffe.AliasResolutionError:  # from another distribution: not ours
                    continue
            if member is not None:
                yield member
        return
    for name, member in obj.members.items():
        if not (name.startswith("_") or member.is_alias):
            yield member


def _undocumented(obj, found, seen):
    """Adds to `found` the paths of obj (a function or class) and of its public methods, or
    of a module's public functions and classes, that have no docstring."""
    if obj.path in seen:
        return
    seen.add(obj.path)
    if (obj.is_function or obj.is_class) and not (obj.docstring and obj.docstring.value.strip()):
        found.append(obj.path)
    if obj.is_module or obj.is_class:
        for member in _public_members(obj):
            if member.is_function or member.is_class:
                _undocumented(member, found, seen)


def undocumented(identifiers, search_paths) -> list[str]:
    """The dotted paths of the public functions, classes and methods without a docstring among
    `identifiers` (modules, classes or functions) and their public members, in the order of
    `__all__` or else of the source.

    search_paths: the folders where the top-level packages are found (mkdocs.yml's
    mkdocstrings `paths`).  An identifier that cannot be found raises PluginError naming it.
    """
    where = [str(p) for p in search_paths]
    loader = griffe.GriffeLoader(search_paths=where)
    objects, packages = [], set()
    for identifier in identifiers:
        try:
            package = identifier.split(".")[0]
            if package not in packages:  # griffe loads a package again if asked
                loader.load(package)
                packages.add(package)
            objects.append(loader.modules_collection[identifier])
        except (ImportError, KeyError) as exc:
            raise PluginError(
                f"docs/{API_DIR}: '::: {identifier}' names no module, class or "
                f"function found in {where} ({exc!r})"
            ) from None
    loader.resolve_aliases(implicit=False, external=False)
    found, seen = [], set()
    for obj in objects:
        _undocumented(obj.final_target if obj.is_alias else obj, found, seen)
    return found


def on_pre_build(config, **kwargs):
    """MkDocs hook: raise PluginError listing the public objects of the API pages without a
    docstring (see the module docstring)."""
    root = Path(config.config_file_path).parent
    python = config.plugins["mkdocstrings"].config.handlers.get("python", {})
    search_paths = [root / p for p in python.get("paths", ["."])]
    missing = undocumented(api_identifiers(config.docs_dir), search_paths)
    if missing:
        raise PluginError(
            f"{len(missing)} public function(s)/class(es) of the API pages have no "
            f"docstring (docs/hooks.py): " + ", ".join(missing)
        )
