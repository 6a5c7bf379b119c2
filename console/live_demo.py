"""``drs demo --live``: the demo world behind the LIVE console, configured from a file as on launch day.

``drs demo`` wires the console to its simulators in memory. A newcomer rehearsing the real release
needs the real path instead: a ``drs.toml`` read from disk (every path absolute, so it works from any
directory and from a second shell), the capsules reached over SSH with pinned host keys, the gateway's
password from the environment (never from the file), the demo weather and terrain given as
``--weather``/``--terrain`` as a live console takes them, and a console in live mode, not demo mode.
The world keeps running in this process: the capsule simulators, the simulated RockBLOCK, the MO
webhook receiver that stores each report, and the ground station sending the balloon's position.

Reports: after Go the simulated capsule falls along the predictor's own physics (demo weather and
terrain, plus a wind error and GNSS noise) and, every INTERVAL, holds an SBD session with the simulated
RockBLOCK; the gateway POSTs each report, JWT-signed as Ground Control signs it, to the receiver, which
writes it to the store the console reads. A PARACHUTE the console queues is downloaded at the next such
session and obeyed as the firmware does (drs_protocol.md 3.8).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from console.demo import DemoWorld
from drs_link.config import Config

PASSWORD_FILE = "gateway-password"
"""The simulated gateway's password, 0600 in the session directory: a second shell reads it from there
(``export DRS_ROCKBLOCK_PASSWORD="$(cat …)"``); it is never printed."""


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    return json.dumps(str(value))  # a TOML basic string is a JSON string for these values


def config_toml(tables: dict[str, object]) -> str:
    """The demo's configuration tables as TOML: plain tables, then each ``[[capsule]]``."""
    lines = []
    for name, table in tables.items():
        rows = table if isinstance(table, list) else [table]
        for row in rows:
            assert isinstance(row, dict)
            lines.append(f"[[{name}]]" if isinstance(table, list) else f"[{name}]")
            lines += [f"{key} = {_toml_value(value)}" for key, value in row.items()]
            lines.append("")
    return "\n".join(lines)


def start_live_demo(root: Path) -> tuple[DemoWorld, Path, Config]:
    """Start the world at the real pace and write its ``drs.toml`` and password file; the world runs until
    ``world.stop()``. The gateway's password is put in this process's environment for the console."""
    world = DemoWorld(root, speed=1.0)
    config = world.start()
    path = root / "drs.toml"
    path.write_text(
        "# drs demo --live: the demo world's capsules, gateway and balloon feed, every path absolute.\n"
        + config_toml(world.config_table),
        encoding="utf-8",
    )
    secret = root / PASSWORD_FILE
    secret.touch(mode=0o600)
    secret.write_text(world.environ["DRS_ROCKBLOCK_PASSWORD"], encoding="utf-8")
    os.environ.update(world.environ)
    return world, path, config


def rehearsal_lines(drs: str, config: Path, world: DemoWorld) -> list[str]:
    """What the newcomer reads before the console opens: where things are and how to reach them."""
    weather = " ".join(str(p) for p in world.weather_files)
    return [
        f"drs demo --live: capsules DRS1-3 over SSH, the simulated RockBLOCK and its reports, in {config.parent}",
        f"  configuration: {config}",
        f"  weather (demo, generated): {weather}",
        f"  terrain: {world.terrain_file.parent}",
        "  from another shell (the world lives as long as this console):",
        f'    export DRS_ROCKBLOCK_PASSWORD="$(cat {config.parent / PASSWORD_FILE})"',
        f"    {drs} --config {config} capsule status DRS1",
        f"  opening: {drs} --config {config} console --weather <the files above> --terrain {world.terrain_file.parent}",
    ]
