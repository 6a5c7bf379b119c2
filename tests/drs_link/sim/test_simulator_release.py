"""End to end through paramiko against the simulated capsule: release, refusals and every fault."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import tomllib
from collections.abc import Callable
from pathlib import Path

import paramiko
import pytest

from drs_link.config import CapsuleConfig, parse_config
from drs_link.errors import LinkError, RefusedError
from drs_link.link import remote
from drs_link.link.backends.stock import StockBackend
from drs_link.link.ssh import CapsuleLink, HostKeyError, LinkDownError, fingerprint
from drs_link.ops.capsule import ReleaseState, ReleaseStateMachine
from drs_link.sim import CapsuleSimulator, GnssSky
from drs_link.sim.firmware import BOOT_S
from drs_link.sim.keys import generate_ed25519
from drs_link.store import Store

pytestmark = pytest.mark.slow


def _machine(
    store: Store, config: CapsuleConfig, sim: CapsuleSimulator, holder: str = "EL@console1"
) -> tuple[ReleaseStateMachine, CapsuleLink]:
    link = CapsuleLink(config)
    machine = ReleaseStateMachine(
        store,
        config,
        StockBackend(config, link),
        "EL",
        clock=sim.clock.now,
        sleep=sim.clock.sleep,
        holder=holder,
    )
    return machine, link


@pytest.fixture
def store(tmp_path: Path) -> Store:
    return Store.open(tmp_path / "drs.sqlite")


def test_power_on_then_confirmed_go_releases_and_the_pi_shuts_down(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim()
    machine, link = _machine(store, sim_config(sim), sim)
    machine.power_on(confirmed=True)
    assert sim.gpio.relay_latched and sim.gpio.tx_mode == "alt5" and not sim.gpio.outputs
    report = machine.wait_for_microcontroller()
    assert report.waiting_for_go and report.gnss.has_fix and report.gnss.satellites == 9
    # NMEA only after the firmware's boot; the machine counts from when power-on returned, a little after
    # the relay latched (more on a loaded machine), so its count is the smaller one.
    since_latched = (sim.clock.now() - sim.firmware.powered_at).total_seconds()  # type: ignore[operator]
    assert since_latched >= BOOT_S
    assert report.seconds_since_power_on is not None and 0 < report.seconds_since_power_on <= since_latched
    released = machine.go(machine.confirm("DRS1"))
    assert released.state is ReleaseState.RELEASED and released.note == "released, Pi shut down"
    assert sim.firmware.go_at is not None and sim.shut_down
    assert [(a.action, a.result) for a in store.audit("DRS1")] == [
        ("power-on", "started"),
        ("power-on", "ok"),
        ("microcontroller", "waiting for Go"),
        ("go-confirmation", "minted"),
        ("go", "sending"),
        ("go", "released, Pi shut down"),
    ]
    log = sim.serial_log.read_text()
    assert "$GPGGA" in log and "Dropping in 30 seconds!" not in log
    link.close()


def test_second_go_to_a_released_capsule_is_refused_without_touching_the_pi(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim()
    machine, _ = _machine(store, sim_config(sim), sim)
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    token = machine.confirm("DRS1")
    machine.go(token)
    commands = len(sim.commands)
    with pytest.raises(RefusedError, match="already released"):
        machine.confirm("DRS1")
    with pytest.raises(RefusedError, match="already released"):
        machine.go(token)
    assert len(sim.commands) == commands


def test_cli_style_go_after_power_on_in_another_process_resumes_from_the_store(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    first, link = _machine(Store.open(tmp_path / "s.sqlite"), config, sim)
    first.power_on(confirmed=True)
    first.wait_for_microcontroller()
    link.close()
    second, _ = _machine(Store.open(tmp_path / "s.sqlite"), config, sim)
    assert second.record().state is ReleaseState.POWERED
    assert second.go(second.confirm("DRS1")).state is ReleaseState.RELEASED


def test_a_second_console_cannot_take_release_authority(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    mine, _ = _machine(Store.open(tmp_path / "a.sqlite"), config, sim, holder="EL@console1")
    theirs, _ = _machine(Store.open(tmp_path / "b.sqlite"), config, sim, holder="JR@console2")
    mine.power_on(confirmed=True)
    with pytest.raises(RefusedError, match="held by EL@console1"):
        theirs.power_on(confirmed=True)
    assert theirs.record().state is ReleaseState.IDLE
    assert [a.result for a in theirs.store.audit("DRS1")] == ["started", "refused"]


def test_go_refused_while_no_nmea_arrived_from_a_unit_left_in_gone_mode(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim(gone=True)
    machine, _ = _machine(store, sim_config(sim, microcontroller_wait_s=25.0), sim)
    machine.power_on(confirmed=True)
    report = machine.wait_for_microcontroller()
    assert (
        not report.waiting_for_go
        and "Gone mode" in report.diagnosis
        and "four-button reset" in report.diagnosis
    )
    with pytest.raises(RefusedError, match="no NMEA seen since power-on"):
        machine.go(machine.confirm("DRS1"))
    assert sim.firmware.go_at is None and not sim.shut_down


def test_dead_batteries_latch_the_relay_but_the_microcontroller_stays_silent(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim(battery=False)
    machine, _ = _machine(store, sim_config(sim), sim)
    machine.power_on(confirmed=True)
    report = machine.wait_for_microcontroller()
    assert sim.gpio.relay_latched and not report.waiting_for_go and "batteries" in report.diagnosis
    assert store.audit("DRS1")[-1].result == "silent"


def test_no_gnss_fix_still_means_waiting_for_go_but_reports_no_position(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim(sky=GnssSky(fix=False))
    machine, _ = _machine(store, sim_config(sim), sim)
    machine.power_on(confirmed=True)
    report = machine.wait_for_microcontroller()
    assert report.waiting_for_go and not report.gnss.has_fix and report.gnss.fix_quality == 0
    assert report.gnss.latitude is None and report.gnss.fix_time_utc is not None


def test_link_dropping_during_power_on_leaves_the_outcome_unknown_and_power_on_again_settles_it(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    """The console cannot tell a link that died before the script from one that died after the relay
    latched (here it died before): either way the record says so, and a second power-on settles it."""
    sim = make_sim()
    machine, _ = _machine(store, sim_config(sim), sim)
    sim.faults.drop_on_command = "power-on"
    with pytest.raises(LinkError, match="link dropped during power-on; power-on outcome unknown"):
        machine.power_on(confirmed=True)
    assert not sim.gpio.relay_latched
    assert machine.record().state is ReleaseState.POWER_ON_UNKNOWN
    assert store.audit("DRS1")[-1].result == "outcome unknown"
    assert machine.power_on(confirmed=True).state is ReleaseState.POWERED and sim.gpio.relay_latched


def test_link_dropping_before_go_output_leaves_go_unverified_and_retry_allowed(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], store: Store
) -> None:
    sim = make_sim()
    machine, _ = _machine(store, sim_config(sim), sim)
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    sim.faults.drop_on_command = "go"
    with pytest.raises(LinkError, match="may or may not have reached"):
        machine.go(machine.confirm("DRS1"))
    assert machine.record().state is ReleaseState.GO_SENT and sim.firmware.go_at is None
    assert machine.go(machine.confirm("DRS1")).state is ReleaseState.RELEASED
    assert sim.firmware.go_at is not None


def test_slow_pi_times_out_the_heartbeat_then_recovers(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    link = CapsuleLink(sim_config(sim))
    sim.faults.response_delay_s = 1.0
    assert not link.heartbeat(timeout_s=0.3)
    sim.faults.response_delay_s = 0.0
    assert link.heartbeat(timeout_s=2.0)
    link.close()


def test_link_cut_after_n_bytes_mid_command_is_reported_as_a_drop_then_reconnects(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    link = CapsuleLink(sim_config(sim))
    assert link.heartbeat()
    sim.faults.response_delay_s = 0.3
    threading.Timer(0.1, sim.faults.arm_drop, args=(1,)).start()
    result = link.run(remote.storage_report("/mnt/raid1"))
    assert result.link_dropped and result.exit_status is None
    sim.faults.response_delay_s = 0.0
    assert link.run(remote.storage_report("/mnt/raid1")).ok
    link.close()


def test_close_from_another_thread_aborts_a_hung_command(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    link = CapsuleLink(sim_config(sim))
    assert link.heartbeat()
    sim.faults.response_delay_s = 5.0
    threading.Timer(0.3, link.close).start()
    result = link.run(remote.heartbeat(), timeout_s=20)
    assert result.link_dropped and not result.timed_out
    sim.faults.response_delay_s = 0.0
    assert link.heartbeat()


def test_dropped_link_reconnects_on_the_next_command(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    link = CapsuleLink(sim_config(sim))
    assert link.heartbeat()
    sim.drop_link()
    assert link.heartbeat()
    link.close()


def test_changed_host_key_is_refused_with_both_fingerprints(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    impostor_key = generate_ed25519()
    sim = make_sim()
    config = sim_config(sim)
    genuine = fingerprint(sim.host_key)
    sim.host_key = impostor_key
    before = config.known_hosts.read_text()
    with pytest.raises(HostKeyError, match="CHANGED") as refused:
        CapsuleLink(config).connect()
    assert fingerprint(impostor_key) in str(refused.value) and genuine in str(refused.value)
    assert config.known_hosts.read_text() == before


def test_unknown_host_is_refused_and_never_added(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    config.known_hosts.write_text("")
    with pytest.raises(HostKeyError, match="not in the known_hosts") as refused:
        CapsuleLink(config).connect()
    assert fingerprint(sim.host_key) in str(refused.value)
    assert config.known_hosts.read_text() == ""


def test_missing_known_hosts_file_is_refused(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    config = sim_config(sim, known_hosts=str(tmp_path / "absent"))
    with pytest.raises(HostKeyError, match="does not exist"):
        CapsuleLink(config).connect()


@pytest.mark.parametrize(
    "damage",
    [
        b"drs1 ssh-ed25519 AAAA!!notbase64\n",
        b"drs1 ssh-rsa AAAAB3NzaC1yc2EAAAADAQABAAAB\n",
        b"\x00\xff\xfe\n",
    ],
    ids=["bad-base64", "truncated-rsa-key", "not-text"],
)
def test_a_damaged_known_hosts_file_is_refused_in_one_line(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], damage: bytes
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    config.known_hosts.write_bytes(sim.known_hosts_line().encode() + damage)
    with pytest.raises(HostKeyError, match="is damaged .*drs capsule enrol"):
        CapsuleLink(config).connect()


def test_wrong_client_key_is_an_authentication_error(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim(authorized_keys=[generate_ed25519()])
    with pytest.raises(LinkError, match="authentication failed"):
        CapsuleLink(sim_config(sim)).connect()


def test_unreachable_capsule_is_retried_with_backoff_then_reported(
    sim_config: Callable[..., CapsuleConfig], make_sim: Callable[..., CapsuleSimulator]
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    sim.stop()
    delays: list[float] = []
    link = CapsuleLink(config, sleep=delays.append)
    with pytest.raises(LinkDownError, match="cannot reach"):
        link.connect_with_retry(attempts=4)
    assert delays == [0.5, 1.0, 2.0]


def test_jump_host_forwards_to_the_capsule_with_both_host_keys_verified(
    make_sim: Callable[..., CapsuleSimulator],
    sim_config: Callable[..., CapsuleConfig],
    client_key: tuple[Path, paramiko.PKey],
    tmp_path: Path,
) -> None:
    flight_computer = make_sim(name="FC")
    capsule = make_sim(name="DRS2")
    known = tmp_path / "known_both"
    known.write_text(flight_computer.known_hosts_line() + capsule.known_hosts_line())
    config = sim_config(capsule, jump_host=f"pi@127.0.0.1:{flight_computer.port}", known_hosts=str(known))
    with CapsuleLink(config) as link:
        result = link.run(remote.heartbeat())
    assert result.ok and any("drs:heartbeat" in c for c in capsule.commands)
    assert not any("drs:heartbeat" in c for c in flight_computer.commands)


def test_arguments_reach_the_pi_quoted(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    with CapsuleLink(sim_config(sim)) as link:
        result = link.run(remote.storage_report("/mnt/raid1; rm -rf /"))
    assert result.exit_status == 1 and "No such file" in result.stderr
    assert "'/mnt/raid1; rm -rf /'" in sim.commands[-1]


def test_simulator_entry_point_serves_capsules_until_terminated(
    client_key: tuple[Path, paramiko.PKey], tmp_path: Path
) -> None:
    known_hosts = tmp_path / "demo_known_hosts"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "drs_link.sim",
            "--name",
            "DRS1",
            "--name",
            "DRS2",
            "--authorized-key",
            f"{client_key[0]}.pub",
            "--known-hosts",
            str(known_hosts),
            "--scale",
            "40",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        lines = []
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("simulators running"):
                break
        printed = tomllib.loads("".join(lines[:-1]))
        config = parse_config(printed)
        assert [c.name for c in config.capsules] == ["DRS1", "DRS2"]
        with CapsuleLink(config.capsule("DRS2")) as link:
            assert link.heartbeat()
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
