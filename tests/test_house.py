"""The house's shape, as docs/architecture.md describes it: rooms with one door each, and no cycles.

import-linter (``make lint``) checks that rooms import only downward; these tests check what it cannot
express: that code outside a room reaches it only through its ``__init__``, that every room says what
it holds, and that no module imports itself back through others at run time.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import grimp
import pytest

from tools.house_diagram import PACKAGES, ROOT, mermaid, rooms


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _rooms() -> list[str]:
    """Every folder below a top-level package, deepest first (the diagram's rooms, without the packages'
    own foundations), so a module belongs to its nearest room."""
    return [room for room in rooms() if "." in room]


def _room_of(module: str, rooms: list[str]) -> str | None:
    """The room ``module`` sits inside; None for a room's own door, which is how others enter it."""
    if module in rooms:
        return None
    return next((room for room in rooms if module.startswith(room + ".")), None)


def _imported_modules(tree: ast.AST) -> list[tuple[int, str]]:
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            found.extend((node.lineno, alias.name) for alias in node.names)
    return found


def test_code_outside_a_room_enters_it_only_by_its_door() -> None:
    rooms = _rooms()
    side_doors = []
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            importer = _module_name(path)
            for line, module in _imported_modules(ast.parse(path.read_text())):
                room = _room_of(module, rooms)
                if room is None:
                    continue
                if importer != room and not importer.startswith(room + "."):
                    side_doors.append(f"{path.relative_to(ROOT)}:{line} imports {module}, not {room}")
    assert side_doors == []


def test_a_module_taken_from_behind_a_door_is_one_the_door_lists() -> None:
    """``from drs_link.iridium import lifecycle`` passes the door's text but takes a module behind it whole:
    a side door, unless the door lists the module (mapped to itself) as something it hands out."""
    rooms = _rooms()
    side_doors = []
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            importer = _module_name(path)
            for node in ast.walk(ast.parse(path.read_text())):
                if not (isinstance(node, ast.ImportFrom) and node.level == 0 and node.module in rooms):
                    continue
                room = node.module
                if importer == room or importer.startswith(room + "."):
                    continue
                folder = ROOT / room.replace(".", "/")
                listed = _door_exports(folder / "__init__.py")
                for alias in node.names:
                    if (folder / f"{alias.name}.py").exists() and listed.get(alias.name) != alias.name:
                        side_doors.append(
                            f"{path.relative_to(ROOT)}:{node.lineno} takes module {room}.{alias.name}"
                        )
    assert side_doors == []


@pytest.mark.parametrize("room", _rooms())
def test_every_room_says_what_it_holds(room: str) -> None:
    door = ROOT / room.replace(".", "/") / "__init__.py"
    docstring = ast.get_docstring(ast.parse(door.read_text()))
    assert docstring and len(docstring) > 40, f"{door} needs a docstring that says what the room holds"


@functools.cache  # a room's door lists each name once, and each was parsed for every file: 20 s of ast.parse
def _defined_at_top(path: Path) -> frozenset[str]:
    names = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {target.id for target in node.targets if isinstance(target, ast.Name)}
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return frozenset(names)


def test_a_door_names_only_what_its_room_defines_once() -> None:
    """A lazy door's name that no module defines would fail only when first used, on launch day; one that
    two modules define (each bench has its ``run_bench``) would open whichever the door happens to name."""
    import importlib

    for room in _rooms():
        door = importlib.import_module(room)
        folder = ROOT / room.replace(".", "/")
        for name in getattr(door, "__all__", ()):
            assert getattr(door, name) is not None, f"{room}.{name}"
            homes = [
                p.stem for p in folder.glob("*.py") if p.name != "__init__.py" and name in _defined_at_top(p)
            ]
            assert len(homes) <= 1, f"{room}.{name} is defined in {homes}: import the module instead"


@pytest.mark.parametrize("package", ["predictor", "drs_link", "console"])
def test_no_module_imports_itself_back_through_others(package: str) -> None:
    """Run-time imports only: an import under ``TYPE_CHECKING`` is a type annotation, never executed."""
    graph = grimp.build_graph(package, exclude_type_checking_imports=True, cache_dir=None)
    cycles = []
    for module in sorted(graph.modules):
        for imported in graph.find_modules_directly_imported_by(module):
            if imported != module and graph.chain_exists(imported=module, importer=imported):
                cycles.append(f"{module} -> {imported} -> … -> {module}")
    assert cycles == []


def test_the_picture_in_the_architecture_doc_is_the_code_as_it_is() -> None:
    """The graph in docs/architecture.md is made by tools/house_diagram.py (``make house``) from grimp's
    import graph: a room that gains or loses a neighbour must be drawn again."""
    assert mermaid() in (ROOT / "docs" / "architecture.md").read_text()


def test_the_tests_live_in_the_room_they_pin() -> None:
    """tests/ mirrors the house: a folder below tests/<package>/ is named for one of that package's rooms."""
    rooms = set(_rooms())
    strays = [
        str(folder.relative_to(ROOT))
        for package in PACKAGES
        if (ROOT / "tests" / package).is_dir()
        for folder in (ROOT / "tests" / package).iterdir()
        if folder.is_dir() and not folder.name.startswith("__") and f"{package}.{folder.name}" not in rooms
    ]
    assert strays == []


ROOM_IMPORT_EXCEPTIONS = {
    "tests/console/test_end_to_end_tmux.py": "drives the installed `drs demo` in a terminal (tmux) and reads "
    "the screen: it pins the whole console as an operator runs it, and imports none of it",
    "tests/predictor/calibration/test_wind_errors_report.py": "pins the committed report of a measurement "
    "script in docs/planning, which it loads by path; the script reaches predictor.calibration",
    "tests/predictor/calibration/test_departure_cadence_report.py": "pins the committed report of a "
    "measurement script in docs/planning, which it loads by path; the script reaches predictor.calibration",
    "tests/predictor/calibration/test_preflight_held_out_report.py": "pins the committed report of a "
    "measurement script in docs/calibration, which it loads by path; the script reaches predictor.calibration",
}
"""Test files that pin their room without reaching it as the rule below counts, each with the reason."""

MODULE_NAME = re.compile(rf"(?:{'|'.join(PACKAGES)})(?:\.\w+)+")


def _reached(path: Path, *, through_helpers: bool = True) -> set[str]:
    """The product modules a test file reaches: those it imports anywhere in the file, a name taken from a
    package's own door counted as the module that door maps it to (``from predictor import predict`` reaches
    ``predictor.prediction.landings``); those it runs as a program (a string that is exactly a module's
    dotted name, as ``python -m`` takes it); and what a helper module in its own folder reaches, when it
    imports that helper (``tests/predictor/geofiles/exports/conftest.py``)."""
    reached: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            reached |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            if node.level == 1:
                helper = path.parent / f"{node.module}.py"
            else:
                helper = ROOT / f"{node.module.replace('.', '/')}.py"
                reached.add(node.module)
                if node.module in PACKAGES:
                    door = (ROOT / node.module / "__init__.py").read_text()
                    listed = _door_map(ast.parse(door)) if "lazy_door(" in door else {}
                    reached |= {f"{node.module}.{listed.get(alias.name, alias.name)}" for alias in node.names}
            if through_helpers and helper.parent == path.parent and helper.exists() and helper != path:
                reached |= _reached(helper, through_helpers=False)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            reached |= {node.value} if MODULE_NAME.fullmatch(node.value) else set()
    return reached


def _room_named_by(test_file: Path) -> str:
    package, *folders = test_file.relative_to(ROOT / "tests").parts[:-1]
    return f"{package}.{folders[0]}" if folders else package


def test_a_test_folders_files_reach_the_room_it_is_named_for() -> None:
    """Each ``tests/<package>/<room>/…/test_*.py`` reaches ``<package>.<room>`` (the room's door or a module
    in it), and each ``tests/<package>/test_*.py`` reaches ``<package>``, as ``_reached`` counts. A file
    that reaches only other rooms pins them, and sits in their folder (or, a command line's test, in
    ``tests/console/commands``). Reaching the room is needed, not enough: a CLI test that imports the
    domain to compare against still belongs with the commands. Helpers (conftest, helpers) are not tests."""
    strays = []
    for package in PACKAGES:
        for path in sorted((ROOT / "tests" / package).rglob("test_*.py")):
            room = _room_named_by(path)
            if not any(module == room or module.startswith(room + ".") for module in _reached(path)):
                strays.append(str(path.relative_to(ROOT)))
    # an exception that no longer strays is struck from the list, so the list stays the truth
    assert sorted(strays) == sorted(ROOM_IMPORT_EXCEPTIONS)


def _lazy_doors() -> list[Path]:
    return sorted(
        path
        for package in PACKAGES
        for path in (ROOT / package).rglob("__init__.py")
        if "lazy_door(" in path.read_text()
    )


def _door_map(tree: ast.Module) -> dict[str, str]:
    """The names a lazy door opens, each with the module (relative to the door) that defines it."""
    call = next(
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "lazy_door"
    )
    exports = call.args[1]
    assert isinstance(exports, ast.Dict)
    return {
        ast.literal_eval(key): ast.literal_eval(value)
        for key, value in zip(exports.keys, exports.values, strict=True)
    }


def _plain_door_map(tree: ast.Module) -> dict[str, str]:
    """The names a plain door imports from its own modules at run time, each with its module."""
    return {
        alias.asname or alias.name: statement.module or alias.name
        for statement in tree.body
        if isinstance(statement, ast.ImportFrom) and statement.level == 1
        for alias in statement.names
    }


def _door_exports(door: Path) -> dict[str, str]:
    """What a door, lazy or plain, hands out: each name with the module (relative to the door) behind it."""
    text = door.read_text()
    return (_door_map if "lazy_door(" in text else _plain_door_map)(ast.parse(text))


def _type_checking_map(tree: ast.Module) -> dict[str, str]:
    """The names the door's ``if TYPE_CHECKING:`` block imports from its own modules, each with its module."""
    found: dict[str, str] = {}
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for statement in node.body:
                if not (isinstance(statement, ast.ImportFrom) and statement.level == 1):
                    continue  # an annotation of the door's own code, not a name it opens
                for alias in statement.names:
                    assert alias.asname in (None, alias.name), f"{alias.name} renamed to {alias.asname}"
                    # ``from . import gpx`` is a module the door hands out whole, mapped to itself
                    found[alias.name] = statement.module or alias.name
    return found


@pytest.mark.parametrize("door", _lazy_doors(), ids=lambda door: str(door.relative_to(ROOT).parent))
def test_a_lazy_doors_type_checking_imports_are_its_map(door: Path) -> None:
    """A type checker and an editor read the ``TYPE_CHECKING`` imports; the program runs the lazy map. The
    two must name the same things from the same modules, or a type would describe a name that is not there.
    """
    tree = ast.parse(door.read_text())
    assert _type_checking_map(tree) == _door_map(tree)


def _doors() -> list[Path]:
    return [ROOT / room.replace(".", "/") / "__init__.py" for room in _rooms()]


def test_no_door_exports_a_private_name() -> None:
    private = [
        f"{door.relative_to(ROOT)}: {name}"
        for door in _doors()
        for name in _door_exports(door)
        if name.startswith("_")
    ]
    assert private == []
