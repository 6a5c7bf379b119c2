"""The agent backend against the simulated capsule: installed and verified over SFTP, acknowledged Go."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError
from drs_link.link.backends.agent import AGENT_SOURCE, AgentBackend
from drs_link.link.ssh import CapsuleLink
from drs_link.ops.capsule import ReleaseState, ReleaseStateMachine
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store

pytestmark = pytest.mark.slow


def _machine(
    tmp_path: Path, config: CapsuleConfig, sim: CapsuleSimulator
) -> tuple[ReleaseStateMachine, AgentBackend]:
    backend = AgentBackend(config, CapsuleLink(config))
    machine = ReleaseStateMachine(
        Store.open(tmp_path / "drs.sqlite"), config, backend, "EL", clock=sim.clock.now, sleep=sim.clock.sleep
    )
    return machine, backend


def test_power_on_installs_the_agent_verified_and_only_once(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    machine, backend = _machine(tmp_path, sim_config(sim, backend="agent"), sim)
    machine.power_on(confirmed=True)
    installed = sim.tools_path / "drs_agent.py"
    assert installed.read_bytes() == AGENT_SOURCE.read_bytes()
    assert not backend.ensure_installed()
    installed.write_text("# tampered\n")
    assert backend.ensure_installed() and installed.read_bytes() == AGENT_SOURCE.read_bytes()


def test_continuous_timestamped_log_and_acknowledged_go(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    machine, _ = _machine(tmp_path, sim_config(sim, backend="agent"), sim)
    machine.power_on(confirmed=True)
    report = machine.wait_for_microcontroller()
    assert report.waiting_for_go and report.gnss.has_fix
    first = sim.agent_log.read_text().splitlines()[0]
    assert first.split(" ", 1)[0].endswith("Z") and "$GPGGA" in first
    released = machine.go(machine.confirm("DRS1"))
    assert released.state is ReleaseState.RELEASED and released.note == "released, Pi shut down"
    assert machine.store.audit("DRS1")[-1].detail == {
        "exit_status": None,
        "link_dropped": True,
        "firmware_acknowledged": True,
    }


def test_go_the_firmware_does_not_acknowledge_keeps_the_pi_up_for_a_retry(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig], tmp_path: Path
) -> None:
    sim = make_sim()
    machine, _ = _machine(tmp_path, sim_config(sim, backend="agent"), sim)
    machine.power_on(confirmed=True)
    machine.wait_for_microcontroller()
    sim.press_off_button()
    with pytest.raises(LinkError, match="did not acknowledge"):
        machine.go(machine.confirm("DRS1"))
    assert not sim.shut_down and machine.record().state is ReleaseState.GO_SENT
