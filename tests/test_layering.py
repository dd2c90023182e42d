"""The core's rooms and their order (rvfmu/core/__init__.py): each room imports only the rooms
before it, function-level imports included; no module imports another in a circle; the core
imports nothing of rvfmu outside itself (the CLI, the FMUs and the plots are layers over it).
"""

import ast
import functools
from pathlib import Path

import pytest

import rvfmu.core

CORE = Path(rvfmu.core.__file__).parent
ROOMS = ("base", "laws", "reducer", "statics", "losses", "dynamics", "steppers")


@functools.cache
def modules() -> dict:
    """{dotted name: path} of every module of the core and its rooms (walked once a run)."""
    out = {}
    for path in sorted(CORE.rglob("*.py")):
        parts = path.relative_to(CORE.parent.parent).with_suffix("").parts
        out[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return out


def imported(name: str, path: Path) -> list:
    """(line, absolute dotted name) of every rvfmu module `path` imports, at any depth of the
    file.  `from X import y` names X.y where that is a module, else X."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    known = modules()
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names if alias.name.startswith("rvfmu")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            if not source.startswith("rvfmu"):
                continue
            for alias in node.names:
                full = f"{source}.{alias.name}"
                out.append((node.lineno, full if full in known else source))
    return out


def room_of(dotted: str) -> str | None:
    """The room of a core module (None for rvfmu.core itself)."""
    parts = dotted.split(".")
    return parts[2] if len(parts) > 2 else None


def test_the_rooms_are_the_folders_and_every_module_lives_in_one():
    folders = {p.name for p in CORE.iterdir() if (p / "__init__.py").is_file()}
    assert folders == set(ROOMS)
    loose = [p.name for p in CORE.glob("*.py") if p.name != "__init__.py"]
    assert loose == [], "a module of the core belongs in a room"
    for room in ROOMS:
        doc = ast.get_docstring(ast.parse((CORE / room / "__init__.py").read_text()))
        assert doc and "May import:" in doc, f"{room}/__init__.py says what it holds and may import"
        allowed = doc.split("May import:", 1)[1]
        for other in ROOMS:
            said = f"`{other}`" in allowed or (other != room and "every other room" in allowed)
            assert said == (ROOMS.index(other) < ROOMS.index(room)), (room, other)


def test_every_import_of_the_core_goes_to_a_room_before_or_to_its_own():
    wrong = []
    for name, path in modules().items():
        here = room_of(name)
        for line, target in imported(name, path):
            if not target.startswith("rvfmu.core"):
                wrong.append(f"{path.relative_to(CORE)}:{line} imports {target}: outside the core")
                continue
            there = room_of(target)
            if here is None or there is None:
                continue
            if ROOMS.index(there) > ROOMS.index(here):
                wrong.append(f"{path.relative_to(CORE)}:{line} ({here}) imports {target} ({there})")
    assert wrong == []


def test_no_module_of_the_core_imports_itself_through_others():
    known = modules()
    graph = {
        name: {
            t
            for _, t in imported(name, path)
            if t in known and t != name and not known[t].name == "__init__.py"
        }
        for name, path in known.items()
    }
    state, cycles = {}, []

    def visit(node, trail):
        state[node] = "open"
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                cycles.append(trail[trail.index(nxt) :] + [nxt])
            elif nxt not in state:
                visit(nxt, trail + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert cycles == []


@pytest.mark.parametrize(
    "source, wrong",
    [
        ("from ..steppers.te_map import TEMap\n", True),  # statics reaching forward
        ("def f():\n    from ..dynamics import modes\n", True),  # also inside a function
        ("from ...fmu import build\n", True),  # out of the core
        ("from ..laws.pin_law import contact\nfrom . import solver\n", False),
    ],
)
def test_the_check_sees_a_wrong_import(tmp_path, source, wrong):
    """The check itself: a module of statics with the import `source` is (or is not) refused."""
    path = tmp_path / "probe.py"  # read as if it were rvfmu/core/statics/probe.py
    path.write_text(source)
    found = [
        t
        for _, t in imported("rvfmu.core.statics.probe", path)
        if not t.startswith("rvfmu.core") or ROOMS.index(room_of(t) or "base") > ROOMS.index("statics")
    ]
    assert bool(found) == wrong
