"""Print the house as a Mermaid graph made from the code's own imports: which room imports which.

docs/architecture.md carries this graph, and tests/test_house.py fails when the two differ, so the
picture a new engineer reads is the code as it is. Run ``make house`` and paste its output there after a
change of rooms.
"""

from __future__ import annotations

from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("console", "drs_link", "predictor")


def rooms() -> list[str]:
    """Every folder of the three packages (a package's own modules form its foundation room)."""
    found = [
        ".".join(init.parent.relative_to(ROOT).parts)
        for package in PACKAGES
        for init in (ROOT / package).rglob("__init__.py")
    ]
    return sorted(found, key=len, reverse=True)


def room_edges() -> set[tuple[str, str]]:
    """(importer room, imported room) for every run-time import between two rooms of one package, and
    (package, package) for an import between packages. A package's own modules (errors, config, the
    store) are its foundation, which every room of it may use: those edges would only add noise."""
    graph = grimp.build_graph(*PACKAGES, exclude_type_checking_imports=True, cache_dir=None)
    all_rooms = rooms()

    def room_of(module: str) -> str:
        return next(room for room in all_rooms if module == room or module.startswith(room + "."))

    edges = set()
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            if imported.split(".")[0] not in PACKAGES:
                continue
            importer_room, imported_room = room_of(module), room_of(imported)
            importer_package, imported_package = importer_room.split(".")[0], imported_room.split(".")[0]
            if importer_package != imported_package:
                edges.add((importer_package, imported_package))
            elif imported_room != imported_package and not (importer_room + ".").startswith(
                imported_room + "."
            ):
                edges.add((importer_room, imported_room))
    return edges


def _node(room: str) -> str:
    return room.replace(".", "_")


def mermaid() -> str:
    lines = ["```mermaid", "graph TD"]
    lines += [f'  {_node(room)}["{room}"]' for room in sorted(rooms()) if "." in room]
    lines += [f"  {_node(a)} --> {_node(b)}" for a, b in sorted(room_edges())]
    lines.append("```")
    return "\n".join(lines)


if __name__ == "__main__":
    print(mermaid())
