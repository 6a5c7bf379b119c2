"""`drs demo --live`: the demo world behind a configuration file a live console (and a second shell) reads."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest

from console.demo import DemoWorld
from console.live_demo import PASSWORD_FILE, start_live_demo
from drs_link.config import load_config
from tests.clock import SkipClock

DRS = "import sys, console.commands.main as c; sys.exit(c.main())"


@pytest.fixture
def live_demo(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[DemoWorld, Path]]:
    monkeypatch.delenv("DRS_ROCKBLOCK_PASSWORD", raising=False)
    world, path, _ = start_live_demo(tmp_path / "session")
    try:
        yield world, path
    finally:
        world.stop()


def _paths(table: object) -> list[str]:
    if isinstance(table, dict):
        return [p for value in table.values() for p in _paths(value)]
    if isinstance(table, list):
        return [p for value in table for p in _paths(value)]
    return [table] if isinstance(table, str) and "/" in table and not table.startswith("http") else []


def test_the_written_configuration_has_absolute_paths_and_no_secret(
    live_demo: tuple[DemoWorld, Path],
) -> None:
    world, path = live_demo
    document = tomllib.loads(path.read_text())
    paths = _paths(document)
    assert paths and all(Path(p).is_absolute() and Path(p).exists() for p in paths), paths
    assert [c["name"] for c in document["capsule"]] == ["DRS1", "DRS2", "DRS3"]
    password = (path.parent / PASSWORD_FILE).read_text()
    assert password and password not in path.read_text()
    assert (path.parent / PASSWORD_FILE).stat().st_mode & 0o077 == 0
    assert load_config(str(path)).capsule("DRS1").sync_source is not None


def test_a_second_shell_elsewhere_reaches_the_capsules_with_the_file_alone(
    live_demo: tuple[DemoWorld, Path], tmp_path: Path
) -> None:
    """What docs/console.md tells a newcomer to type in another shell: another directory, the
    password from its file, `drs --config … capsule status DRS1` over SSH with the pinned host key."""
    _, path = live_demo
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {**os.environ, "DRS_ROCKBLOCK_PASSWORD": (path.parent / PASSWORD_FILE).read_text()}
    ran = subprocess.run(
        [sys.executable, "-c", DRS, "--config", str(path), "capsule", "status", "DRS1"],
        cwd=elsewhere, env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert ran.returncode == 0, ran.stderr
    assert "link: up" in ran.stdout


def test_live_refuses_a_time_scale_and_a_pipe_in_one_line() -> None:
    for argv, said in [
        (["demo", "--live", "--speed", "4"], "--live runs at the real pace"),
        (["demo", "--live"], "not a terminal"),
    ]:
        ran = subprocess.run([sys.executable, "-c", DRS, *argv], capture_output=True, text=True, timeout=60)
        assert ran.returncode != 0 and ran.stderr.startswith("drs: error: ") and said in ran.stderr, (
            ran.stderr
        )
        assert ran.stderr.count("\n") == 1


@pytest.mark.asyncio
async def test_the_live_console_from_the_file_powers_on_and_arms_a_simulated_capsule(
    live_demo: tuple[DemoWorld, Path], skip_clock: SkipClock
) -> None:
    """The rehearsal itself up to ARM: the console in LIVE mode from the written file, the demo weather as
    --weather, sync, power-on over SSH, a GO poll (gateway configured from the file) and the ARM window."""
    from dataclasses import replace

    from console.app import DrsConsole
    from console.commands.console import live_setup
    from drs_link.ops.arming import ArmState
    from tests.console.conftest import wait_for
    from tests.console.test_release_flow import booting, open_release_go

    world, path = live_demo
    setup = live_setup(load_config(str(path)), world.weather_files, world.terrain_file.parent)
    app = DrsConsole(replace(setup, poll_period_s=0.5))
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            assert setup.mode == "live"
            await open_release_go(pilot, app, booting(skip_clock, world.speed))
            assert {i.key: i.verdict.value for i in app.gonogo("DRS1").items}["gateway"] == "GO"
            await pilot.press("a")
            await wait_for(pilot, lambda: app.context.arming("DRS1").status().state is ArmState.ARMED)
    finally:
        setup.close()
