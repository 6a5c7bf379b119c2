"""The `drs capsule` and `drs sync` commands against a simulated capsule: exit codes and one-line errors."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
import tomllib
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import paramiko
import pytest

import console.commands.main
from drs_link.config import load_config
from drs_link.errors import LinkError, StoreError
from drs_link.link.ssh import fingerprint
from drs_link.ops.capsule import ConfirmationToken, ReleaseRecord, ReleaseStateMachine
from drs_link.ops.checklist import PROCEDURE_DIR, ChecklistRun, StepState, load_checklists
from drs_link.ops.operator_ops import OperatorOps
from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import generate_ed25519
from drs_link.store import Store
from tests.drs_link.conftest import capsule_table
from tests.release_helpers import ROCKBLOCK_PASSWORD_ENV, ROCKBLOCK_TOML, release_args, write_weather

pytestmark = pytest.mark.slow


@pytest.fixture(autouse=True)
def _private_server_in_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """`drs` acts through its private operations server; here in a thread of this process, so what these
    tests watch or patch in the operations layer is what the server runs (drs_link.server.private)."""
    monkeypatch.setenv("DRS_PRIVATE_SERVER", "thread")


def _toml(value: Any) -> str:
    if isinstance(value, str):
        return json.dumps(value)
    return str(value).lower() if isinstance(value, bool) else str(value)


def _write_config(tmp_path: Path, sims: list[CapsuleSimulator], key: Path, operator: str = "EL") -> Path:
    known_hosts = tmp_path / "known_hosts"
    known_hosts.write_text("".join(sim.known_hosts_line() for sim in sims))
    lines = [f"[operator]\nname = {_toml(operator)}", f"[data]\ndir = {_toml(str(tmp_path / 'data'))}",
             ROCKBLOCK_TOML]  # fmt: skip
    for sim in sims:
        table = capsule_table(sim, key, known_hosts=str(known_hosts), python="python3")
        lines.append("[[capsule]]\n" + "\n".join(f"{k} = {_toml(v)}" for k, v in table.items()))
    path = tmp_path / "drs.toml"
    path.write_text("\n".join(lines) + "\n")
    tomllib.loads(path.read_text())
    return path


@pytest.fixture(autouse=True)
def rockblock_password(monkeypatch: pytest.MonkeyPatch) -> None:
    """The gateway credentials go/no-go checks (``drs capsule arm``/``go``), for this process and its children."""
    monkeypatch.setenv(ROCKBLOCK_PASSWORD_ENV, "pw")


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return write_weather(tmp_path_factory.mktemp("gfs"))


def arm_and_go(config: Path, weather: list[Path], confirm: str = "DRS1") -> int:
    """`drs capsule arm` then `drs capsule go`, as the release-day procedure runs them; the go's exit code."""
    assert drs(config, "capsule", "arm", "DRS1", *release_args(weather)) == 0
    return drs(config, "capsule", "go", "DRS1", "--confirm", confirm, *release_args(weather))


@pytest.fixture
def setup(
    make_sim: Callable[..., CapsuleSimulator], client_key: tuple[Path, paramiko.PKey], tmp_path: Path
) -> tuple[CapsuleSimulator, Path]:
    sim = make_sim()
    return sim, _write_config(tmp_path, [sim], client_key[0])


def drs(config: Path, *args: str) -> int:
    return console.commands.main.main(["--config", str(config), *args])


def _one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("drs: error: "), err
    return err[0]


def test_status_json_before_power_on(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    _, config = setup
    assert drs(config, "capsule", "status", "DRS1", "--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert report["release"]["state"] == "idle" and report["link"]["up"]
    assert report["storage"]["raid_state"] == "healthy" and report["storage"]["mount"] == "/mnt/raid1"


def test_full_release_from_the_command_line(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    weather: list[Path],
) -> None:
    sim, config = setup
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    out = capsys.readouterr().out
    assert "Software cannot switch it off again" in out and "waiting for Go" in out
    assert drs(config, "capsule", "status", "DRS1", "--json") == 0
    report = json.loads(capsys.readouterr().out)
    assert report["release"]["state"] == "powered" and report["gnss"]["has_fix"]
    assert report["microcontroller"]["waiting_for_go"]
    assert arm_and_go(config, weather) == 0
    assert "released, Pi shut down" in capsys.readouterr().out
    assert sim.firmware.go_at is not None
    assert drs(config, "capsule", "go", "DRS1", "--confirm", "DRS1") == 1
    assert "FIRE refused: the capsule is fired" in _one_line_error(capsys)
    assert drs(config, "capsule", "status", "DRS1") == 0
    assert "released" in capsys.readouterr().out


def test_go_says_each_step_as_it_starts(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    weather: list[Path],
) -> None:
    """Go takes about 12 s; the trial saw nothing until it ended. What was printed before Go left counts."""
    _, config = setup
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    capsys.readouterr()
    printed_before_go: list[str] = []
    go = ReleaseStateMachine.go

    def watched_go(machine: ReleaseStateMachine, token: ConfirmationToken) -> ReleaseRecord:
        # The server says each step before it takes it; the client prints what streams back a moment
        # later, so what was said before Go left is read until it is there (5 s bound), not at one instant.
        out, deadline = "", time.monotonic() + 5.0
        while "sending Go" not in out and time.monotonic() < deadline:
            out += capsys.readouterr().out
            time.sleep(0.02)
        printed_before_go.append(out)
        return go(machine, token)

    monkeypatch.setattr(ReleaseStateMachine, "go", watched_go)
    assert arm_and_go(config, weather) == 0
    assert len(printed_before_go) == 1
    assert "DRS1: polling go/no-go again" in printed_before_go[0]
    assert "DRS1: sending Go over SSH" in printed_before_go[0]
    assert "released, Pi shut down" in capsys.readouterr().out


def test_go_with_a_confirmation_naming_another_capsule_is_refused(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    weather: list[Path],
) -> None:
    sim, config = setup
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    capsys.readouterr()
    assert arm_and_go(config, weather, confirm="DRS2") == 1
    said = capsys.readouterr()
    assert "does not name 'DRS1'" in said.err
    assert "sending Go" not in said.out  # said only once every rule held, never above a refusal
    assert sim.firmware.go_at is None


def test_go_before_power_on_is_refused(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    weather: list[Path],
) -> None:
    sim, config = setup
    assert drs(config, "capsule", "arm", "DRS1", *release_args(weather)) == 1
    assert "ARM refused: NO-GO: " in (refused := _one_line_error(capsys))
    assert "Power-on done: power-on has not succeeded" in refused
    assert drs(config, "capsule", "go", "DRS1", "--confirm", "DRS1") == 1
    assert "FIRE refused: not armed" in _one_line_error(capsys)
    assert not any("drs:go" in c for c in sim.commands)


def test_power_on_without_yes_and_without_a_terminal_is_refused(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    sim, config = setup
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert drs(config, "capsule", "power-on", "DRS1") == 1
    assert "pass --yes" in _one_line_error(capsys)
    assert not sim.gpio.relay_latched


def test_release_steps_need_an_operator_name(
    make_sim: Callable[..., CapsuleSimulator],
    client_key: tuple[Path, paramiko.PKey],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    config = _write_config(tmp_path, [make_sim()], client_key[0], operator="")
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 1
    assert "operator.name" in _one_line_error(capsys)


def test_unknown_capsule_and_missing_config_are_one_line_errors(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    _, config = setup
    assert drs(config, "capsule", "status", "DRS9") == 1
    assert "no capsule named 'DRS9'" in _one_line_error(capsys)
    assert drs(tmp_path / "none.toml", "capsule", "status", "DRS1") == 1
    assert "does not exist" in _one_line_error(capsys)


def test_status_of_an_unreachable_capsule_says_link_down(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, config = setup
    sim.stop()
    assert drs(config, "capsule", "status", "DRS1", "--json") == 4
    report = json.loads(capsys.readouterr().out)
    assert report["link"]["up"] is False and "cannot reach" in report["link"]["error"]


def test_wrong_host_key_is_a_one_line_refusal(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    sim, config = setup
    sim.host_key = generate_ed25519()
    assert drs(config, "capsule", "status", "DRS1") == 1
    line = _one_line_error(capsys)
    assert "CHANGED" in line and fingerprint(sim.host_key) in line


def test_enrol_shows_the_fingerprint_and_saves_only_a_matching_one(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    sim, config = setup
    known_hosts = tmp_path / "known_hosts"
    known_hosts.write_text("")
    assert drs(config, "capsule", "enrol", "DRS1") == 1
    assert fingerprint(sim.host_key) in capsys.readouterr().out
    assert known_hosts.read_text() == ""
    assert drs(config, "capsule", "enrol", "DRS1", "--fingerprint", "SHA256:wrong") == 1
    assert "enrol refused" in _one_line_error(capsys)
    assert drs(config, "capsule", "enrol", "DRS1", "--fingerprint", fingerprint(sim.host_key)) == 0
    assert drs(config, "capsule", "status", "DRS1") == 0


def test_sync_command_uploads_and_audits(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    sim, config = setup
    source = tmp_path / "payload"
    source.mkdir()
    (source / "data.bin").write_bytes(b"x" * 70_000)
    assert drs(config, "sync", "DRS1", str(source), "--status") == 1
    assert "1 missing" in capsys.readouterr().out
    assert drs(config, "sync", "DRS1", str(source)) == 0
    assert "1 files uploaded and verified" in capsys.readouterr().out
    assert (sim.storage_dir / "data.bin").read_bytes() == b"x" * 70_000
    assert drs(config, "sync", "DRS1", str(source), "--status", "--json") == 0
    assert json.loads(capsys.readouterr().out)["bytes_pending"] == 0
    audit = Store.open(tmp_path / "data" / "drs.sqlite").audit("DRS1")
    assert [(a.action, a.result) for a in audit] == [("sync-file", "verified"), ("sync", "ok")]


def test_the_consoles_sync_is_the_clis_path_with_progress_and_the_same_audit(
    setup: tuple[CapsuleSimulator, Path], tmp_path: Path
) -> None:
    """The console's Sync key (``OperatorOps.sync`` on the configured source) used to upload unaudited."""
    sim, config_path = setup
    source = tmp_path / "payload"
    source.mkdir()
    (source / "a.bin").write_bytes(b"a" * 50_000)
    config = load_config(config_path)
    config = replace(config, capsules=(replace(config.capsules[0], sync_source=source),))
    store = Store.open(config.store_path)
    ops = OperatorOps(config, store)
    progress: list[tuple[str, int, int]] = []
    try:
        assert list(ops.links.sync_status("DRS1").missing) == ["a.bin"]
        report = ops.links.sync("DRS1", on_progress=lambda *seen: progress.append(seen))
        assert list(report.uploaded) == ["a.bin"] and progress[-1] == ("a.bin", 50_000, 50_000)
        assert (sim.storage_dir / "a.bin").read_bytes() == b"a" * 50_000
        sim.stop()
        (source / "b.bin").write_bytes(b"b")
        with pytest.raises(LinkError):
            ops.links.sync("DRS1")
    finally:
        ops.close()
    audit = [(a.action, a.result, a.operator) for a in store.audit("DRS1")]
    assert audit == [("sync-file", "verified", "EL"), ("sync", "ok", "EL"), ("sync", "failed", "EL")]


def test_sync_without_a_directory_uploads_the_capsules_sync_source(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """`drs sync NAME` asked for SOURCE_DIR although the capsule's sync_source names it; and without one
    configured it says which key to set."""
    sim, config = setup
    assert drs(config, "sync", "DRS1") == 1
    assert "sync_source is not configured (set it in the capsule's [[capsule]] table" in _one_line_error(
        capsys
    )
    source = tmp_path / "payload"
    source.mkdir()
    (source / "frame.bin").write_bytes(b"f" * 1000)
    config.write_text(config.read_text().replace('name = "DRS1"', f'name = "DRS1"\nsync_source = "{source}"'))
    assert drs(config, "sync", "DRS1", "--status") == 1
    assert drs(config, "sync", "DRS1") == 0
    assert (sim.storage_dir / "frame.bin").read_bytes() == b"f" * 1000


def test_arm_names_the_missing_sync_source_rather_than_no_data(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], weather: list[Path]
) -> None:
    _, config = setup
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    capsys.readouterr()
    assert drs(config, "capsule", "arm", "DRS1", "--weather", *map(str, weather)) == 1
    [sync] = [line for line in capsys.readouterr().out.splitlines() if "Storage sync complete" in line]
    assert "NO-GO" in sync and "sync_source is not configured" in sync and "no data" not in sync


def test_sync_of_a_missing_directory_is_a_one_line_error(
    setup: tuple[CapsuleSimulator, Path], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    _, config = setup
    assert drs(config, "sync", "DRS1", str(tmp_path / "absent")) == 1
    assert "is not a directory" in _one_line_error(capsys)


def test_bench_measures_against_a_local_simulator(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    config = tmp_path / "drs.toml"
    config.write_text("")
    assert drs(config, "capsule", "bench", "--mb", "1", "--rounds", "3") == 0
    out = capsys.readouterr().out
    assert "heartbeat round trip" in out and "MiB/s" in out and "Pi shut down" in out


def test_bench_rejects_a_non_positive_size(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    config = tmp_path / "drs.toml"
    config.write_text("")
    assert drs(config, "capsule", "bench", "--mb", "0") == 2
    assert "--mb must be positive" in _one_line_error(capsys)


def _done_steps(store: Store) -> dict[str, str | None]:
    """Every checklist step of DRS1 marked done, with the result it was marked with."""
    return {
        status.step.id: status.note
        for checklist in load_checklists(PROCEDURE_DIR)
        for status in ChecklistRun(store, checklist, "DRS1").statuses({})
        if status.state is StepState.DONE
    }


def test_power_on_go_and_reset_tick_their_steps_from_the_cli_as_from_the_console(
    make_sim: Callable[..., CapsuleSimulator],
    client_key: tuple[Path, paramiko.PKey],
    tmp_path: Path,
    weather: list[Path],
) -> None:
    """One rule (drs_link.ops.checklist.complete_command): the CLI used to tick nothing."""
    for side in ("cli", "console"):
        (tmp_path / side).mkdir()
    cli_config = _write_config(tmp_path / "cli", [make_sim()], client_key[0])
    assert drs(cli_config, "capsule", "power-on", "DRS1", "--yes") == 0
    assert arm_and_go(cli_config, weather) == 0
    cli_store = Store.open(tmp_path / "cli" / "data" / "drs.sqlite")
    assert _done_steps(cli_store) == {"power-on": "relay latched", "fire": "released, Pi shut down"}
    assert drs(cli_config, "capsule", "reset", "DRS1", "--confirm", "DRS1") == 0
    # The reset starts the next flight: the last flight's power-on and FIRE are no longer ticked.
    assert _done_steps(cli_store) == {"reset-state": "release state reset"}

    console_config = _write_config(tmp_path / "console", [make_sim()], client_key[0])
    console_store = Store.open(tmp_path / "console" / "data" / "drs.sqlite")
    operations = OperatorOps(load_config(console_config), console_store)
    try:
        operations.links.power_on("DRS1")
        operations.links.reset("DRS1", "DRS1")
    finally:
        operations.close()
    console_steps = _done_steps(console_store)
    assert {k: console_steps[k] for k in ("power-on", "reset-state")} == {
        "power-on": "relay latched",
        "reset-state": "release state reset",
    }


DRS_IN_A_CHILD = "import sys, console.commands.main; sys.exit(console.commands.main.main(sys.argv[1:]))"


def _kill_when(
    config: Path, argv: list[str], store: Store, state: str, also: Callable[[], bool] = lambda: True
) -> None:
    """Run ``drs argv`` in a child process and kill -9 it once the store says ``state`` (and ``also()``)."""
    child = subprocess.Popen([sys.executable, "-c", DRS_IN_A_CHILD, "--config", str(config), *argv])
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and child.poll() is None:
            try:
                rows = store.query("SELECT state FROM release_state WHERE capsule = 'DRS1'")
            except StoreError:
                rows = []  # the child has not created its tables yet
            if rows and rows[0]["state"] == state and also():
                break
            time.sleep(0.05)
        assert child.poll() is None, f"drs {' '.join(argv)} ended before it could be killed at {state}"
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()


def test_go_killed_while_the_pi_runs_it_stays_unverified_and_reset_is_refused(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
) -> None:
    sim, config = setup
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    assert drs(config, "capsule", "arm", "DRS1", *release_args(weather)) == 0
    sim.faults.slow_command = ("go", 20.0)
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    argv = ["capsule", "go", "DRS1", "--confirm", "DRS1", *release_args(weather)]
    _kill_when(config, argv, store, "go-sent-unverified")
    sim.faults.slow_command = None
    capsys.readouterr()
    assert drs(config, "capsule", "status", "DRS1", "--json") == 0
    assert json.loads(capsys.readouterr().out)["release"]["state"] == "go-sent-unverified"
    assert drs(config, "capsule", "reset", "DRS1", "--confirm", "DRS1") == 1
    assert "Go was sent and not verified" in _one_line_error(capsys)


def _go_killed_after_gogogo(
    sim: CapsuleSimulator, config: Path, store: Store, weather: list[Path], monkeypatch: pytest.MonkeyPatch
) -> str:
    """Power on, then kill ``drs capsule go`` once the Pi has written GoGoGo; returns the recorded Go time.

    The Pi's script dies on its next write to the dead session (as the stock script does on a broken
    pipe), so the Pi stays up and the microcontroller has its Go. That write comes 5 s after GoGoGo: under
    load (CI with two CPU hogs, 2026-12-03) the kill once came later, the Pi had halted, and the finishing
    Go found no Pi. So the script's pause after GoGoGo lasts until the kill is done."""
    killed = threading.Event()
    pause = sim.clock.sleep

    def held(seconds: float) -> None:
        if sim.firmware.go_at is not None:
            killed.wait(timeout=120)
        pause(seconds)

    monkeypatch.setattr(sim.clock, "sleep", held)
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    assert drs(config, "capsule", "arm", "DRS1", *release_args(weather)) == 0
    argv = ["capsule", "go", "DRS1", "--confirm", "DRS1", *release_args(weather)]
    try:
        _kill_when(config, argv, store, "go-sent-unverified", lambda: sim.firmware.go_at is not None)
    finally:
        killed.set()
    [row] = store.query("SELECT state, go_at FROM release_state WHERE capsule = 'DRS1'")
    assert row["state"] == "go-sent-unverified"
    return str(row["go_at"])


def test_go_killed_after_the_pi_wrote_gogogo_is_finished_by_its_holder_keeping_the_first_go_time_beside(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sim, config = setup
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    go_at = _go_killed_after_gogogo(sim, config, store, weather, monkeypatch)
    assert drs(config, "capsule", "go", "DRS1", "--confirm", "DRS1") == 0
    assert "released, Pi shut down" in capsys.readouterr().out
    [row] = store.query("SELECT state, go_at, failed_go_at FROM release_state WHERE capsule = 'DRS1'")
    assert (row["state"], row["failed_go_at"]) == ("released", go_at), "the failed attempt's time kept beside"
    assert row["go_at"] > go_at, "the release time is the verified Go's (issue #29)"


def test_go_killed_with_a_pi_that_then_halted_is_settled_released_by_the_operator_with_evidence(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """With the Pi halted no Go retry can confirm the release and reset is refused: that left no way out.
    The operator records it released with the evidence (the release time is the Go's); then reset works."""
    sim, config = setup
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    go_at = _go_killed_after_gogogo(sim, config, store, weather, monkeypatch)
    sim.stop()  # the Pi halted
    capsys.readouterr()
    assert drs(config, "capsule", "go", "DRS1", "--confirm", "DRS1") == 1
    assert "DRS1" in _one_line_error(capsys)
    assert drs(config, "capsule", "reset", "DRS1", "--confirm", "DRS1") == 1
    assert "record it released with the evidence (drs capsule released)" in _one_line_error(capsys)
    evidence = "Iridium reports falling from 27 km"
    assert drs(config, "capsule", "released", "DRS1", "--evidence", evidence, "--confirm", "DRS1") == 0
    assert evidence in capsys.readouterr().out
    [row] = store.query("SELECT state, released_at FROM release_state WHERE capsule = 'DRS1'")
    assert (row["state"], row["released_at"]) == ("released", go_at)
    assert drs(config, "capsule", "reset", "DRS1", "--confirm", "DRS1") == 0


def _status(config: Path, capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    capsys.readouterr()
    assert drs(config, "capsule", "status", "DRS1", "--json") == 0
    return json.loads(capsys.readouterr().out)  # type: ignore[no-any-return]


def test_power_on_killed_before_the_pi_ran_it_is_outcome_unknown_and_reset_settles_it(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
) -> None:
    """Killed after the attempt was recorded and before the Pi ran the script: the console cannot know
    which, so it says so; Go is refused until the operator, having found the relay off, resets."""
    sim, config = setup
    sim.faults.response_delay_s = 20.0
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    _kill_when(config, ["capsule", "power-on", "DRS1", "--yes"], store, "power-on-unknown")
    sim.faults.response_delay_s = 0.0
    release = _status(config, capsys)["release"]
    assert (
        release["state"] == "power-on-unknown"
        and "power-on outcome unknown: check the relay" in release["note"]
    )
    assert not sim.gpio.relay_latched
    assert drs(config, "capsule", "arm", "DRS1", *release_args(weather)) == 1
    assert "Power-on done: power-on has not succeeded" in _one_line_error(capsys)
    assert drs(config, "capsule", "reset", "DRS1", "--confirm", "DRS1") == 0
    assert _status(config, capsys)["release"]["state"] == "idle"


def test_power_on_killed_after_the_pi_latched_the_relay_is_outcome_unknown_and_power_on_again_settles_it(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
) -> None:
    """The Pi ran the script (the relay is latched) and the console died before it heard: this once left
    'idle' over a latched relay. Power-on again (a second SET pulse changes nothing) gives the session Go needs."""
    sim, config = setup
    sim.faults.answer_delay_s = 20.0
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    _kill_when(
        config,
        ["capsule", "power-on", "DRS1", "--yes"],
        store,
        "power-on-unknown",
        lambda: sim.gpio.relay_latched,
    )
    sim.faults.answer_delay_s = 0.0
    assert _status(config, capsys)["release"]["state"] == "power-on-unknown"
    assert drs(config, "capsule", "power-on", "DRS1", "--yes") == 0
    assert _status(config, capsys)["release"]["state"] == "powered"
    assert arm_and_go(config, weather) == 0
    assert "released, Pi shut down" in capsys.readouterr().out and sim.firmware.go_at is not None


def test_power_on_killed_while_waiting_for_the_microcontroller_is_kept_and_go_proceeds(
    setup: tuple[CapsuleSimulator, Path],
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    weather: list[Path],
) -> None:
    sim, config = setup
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    _kill_when(config, ["capsule", "power-on", "DRS1", "--yes"], store, "powered")
    deadline = time.monotonic() + 60
    while True:  # as an operator would: the status reads the serial log until the microcontroller talks
        capsys.readouterr()
        assert drs(config, "capsule", "status", "DRS1", "--json") == 0
        report = json.loads(capsys.readouterr().out)
        assert report["release"]["state"] == "powered"
        if report["microcontroller"]["waiting_for_go"] or time.monotonic() > deadline:
            break
        time.sleep(0.5)
    assert arm_and_go(config, weather) == 0
    assert "released, Pi shut down" in capsys.readouterr().out and sim.firmware.go_at is not None
