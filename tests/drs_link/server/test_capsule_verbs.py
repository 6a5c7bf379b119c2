"""The capsule's steps other than ARM and FIRE, and the MT lifecycle, through a real shared `drs server`:
the capsule simulator behind a real sshd, two real accounts. Each verb works from the command line of an
account that holds neither the store nor the Pi's key; a refusal is the operations layer's own one line;
and under `require_second_operator` one account alone cannot take over the release authority (a typed
name, a waiver, its own approval), while a second account's live `drs approve` lets it go ahead."""

from __future__ import annotations

import json
import pwd
from pathlib import Path

import pytest

from drs_link.link.ssh import fingerprint
from drs_link.ops.capsule import default_holder
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store
from tests.drs_link.server.conftest import IMEI
from tests.drs_link.server.team import Server, Team, client_config, drs, drs_waiting, needs_root

pytestmark = [needs_root, pytest.mark.slow]
TAKE_OVER = (
    "capsule",
    "authority",
    "DRS1",
    "--take-over",
    "--reason",
    "EL's console died",
    "--confirm",
    "DRS1",
)


def audit(place: Path, action: str) -> list[tuple[str, str, dict[str, object] | None]]:
    store = Store.open(place / "state" / "drs.sqlite")
    try:
        return [(a.operator, a.result, a.detail) for a in store.audit("DRS1") if a.action == action]
    finally:
        store.close()


def test_status_power_on_authority_reset_and_released_act_through_the_server_as_each_account(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    sim, _ = capsule_server
    alice, bob = client_config(place, team.alice), client_config(place, team.bob)
    code, out = drs(team.alice, alice, "capsule", "status", "DRS1", "--json")
    report = json.loads(out)
    assert code == 0 and report["release"]["state"] == "idle" and report["link"] == {"up": True}, out
    assert report["storage"]["raid_state"] == "healthy" and "gnss" not in report

    code, out = drs(team.alice, alice, "capsule", "power-on", "DRS1", "--yes")
    assert code == 0 and "Software cannot switch it off again" in out and "waiting for Go" in out, out
    assert sim.gpio.relay_latched
    code, out = drs(team.bob, bob, "capsule", "status", "DRS1")
    assert code == 0 and out.startswith("DRS1: powered\n  link: up\n") and "  GNSS: " in out, out
    el, jm = default_holder("EL"), default_holder("JM")
    code, out = drs(team.alice, alice, "capsule", "authority", "DRS1")
    assert (
        code == 0
        and out.startswith(f"DRS1: release authority held by {el} until ")
        and out.endswith(" s left) (this console)\n")
    ), out
    code, out = drs(team.bob, bob, "capsule", "authority", "DRS1")
    assert code == 0 and "(this console)" not in out, out
    code, out = drs(team.bob, bob, "capsule", "authority", "DRS1", "--release", "--reason", "not mine")
    assert code == 1 and out.startswith("drs: error: DRS1: ") and out.count("\n") == 1, out
    assert f"the release authority belongs to {el}, not to this console" in out

    code, out = drs(team.bob, bob, "capsule", "reset", "DRS1", "--confirm", "DRS2")
    assert (
        code == 1 and out == "drs: error: DRS1: reset refused: the confirmation 'DRS2' does not name 'DRS1'\n"
    )
    code, out = drs(
        team.bob, bob, "capsule", "released", "DRS1", "--evidence", "seen falling", "--confirm", "DRS1"
    )
    assert code == 1 and out.startswith("drs: error: DRS1: released refused: ") and out.count("\n") == 1, out
    code, out = drs(team.bob, bob, "capsule", "reset", "DRS1", "--confirm", "DRS1")
    assert (code, out) == (0, "DRS1: reset to idle\n")
    code, out = drs(team.alice, alice, "capsule", "status", "DRS9")
    assert (code, out) == (1, "drs: error: no capsule named 'DRS9' in the configuration\n")
    assert [(who, result) for who, result, _ in audit(place, "reset")] == [("JM", "refused"), ("JM", "ok")]
    assert [who for who, result, _ in audit(place, "power-on") if result == "ok"] == ["EL"]

    code, out = drs(
        team.alice, alice, "capsule", "authority", "DRS1", "--release", "--reason", "end of shift"
    )
    assert code == 0 and out.startswith(f"DRS1: release authority given up; it was held by {el}"), out
    assert sim.authority is None and jm != el


def test_one_account_alone_cannot_take_over_the_release_authority_and_a_second_accounts_approval_can(
    powered: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    sim, _ = powered
    alice, bob = client_config(place, team.alice), client_config(place, team.bob)
    el, jm = default_holder("EL"), default_holder("JM")
    assert sim.authority is not None and sim.authority[0] == el
    for given, words in (
        ((), "a second login's approval is needed"),
        (("--second-operator", "EL"), "a typed second operator is not accepted"),
        (("--single-operator-waiver", "alone tonight"), "a single-operator waiver is not accepted"),
    ):
        code, out = drs(team.bob, bob, *TAKE_OVER, *given)
        assert code == 1 and f"DRS1: take-over refused: require_second_operator is on: {words}" in out, out
        assert out.count("drs: error: ") == 1 and "--await-approval" in out, out
    assert sim.authority[0] == el, "the holder is unchanged"

    waiting = drs_waiting(team.bob, bob, *TAKE_OVER, "--await-approval")
    lines = []
    while not (line := waiting.readline()).startswith("approval #"):
        assert line, f"the take-over ended before asking: {''.join(lines)}"
        lines.append(line)
    assert lines[0].startswith(f"DRS1: release authority held by {el} until ")
    assert line.startswith("approval #1: waiting for another account to run `drs approve 1`")
    code, out = drs(team.bob, bob, "approve", "1")
    assert code == 1 and f"the same login ({team.bob}) that requested it cannot approve it" in out, out
    assert sim.authority[0] == el, "nothing is asked of the Pi while it waits"
    code, out = drs(team.alice, alice, "approve", "1")
    assert code == 0 and "approved by EL" in out, out
    code, out = waiting.result()
    assert code == 0, out
    assert f"approval #1: approved by EL ({team.alice})" in out
    assert f"DRS1: release authority taken over from {el}: held by {jm} until " in out
    assert sim.authority[0] == jm
    results = [(who, result) for who, result, _ in audit(place, "authority-take-over")]
    assert results[-3:] == [("JM", "approved"), ("JM", "started"), ("JM", f"taken over from {el}")]
    assert [result for _, result, _ in audit(place, "authority-take-over")].count("refused") == 3
    uids = [d["uid"] for _, _, d in audit(place, "approval.peer") if d]
    assert uids == [pwd.getpwnam(team.bob).pw_uid, pwd.getpwnam(team.alice).pw_uid]


def test_enrol_and_the_mt_lifecycle_go_through_the_server_which_writes_its_own_files(
    capsule_server: tuple[CapsuleSimulator, Server], place: Path, team: Team
) -> None:
    sim, _ = capsule_server
    alice = client_config(place, team.alice)
    known_hosts = place / "known_hosts"
    before = known_hosts.read_text()
    code, out = drs(team.alice, alice, "capsule", "enrol", "DRS1")
    assert code == 1 and fingerprint(sim.host_key) in out, out
    code, out = drs(team.alice, alice, "capsule", "enrol", "DRS1", "--fingerprint", "SHA256:wrong")
    assert code == 1 and "enrol refused: the Pi offers" in out and out.count("drs: error: ") == 1, out
    assert known_hosts.read_text() == before
    code, out = drs(team.alice, alice, "capsule", "enrol", "DRS1", "--fingerprint", fingerprint(sim.host_key))
    assert code == 0 and out.endswith(f"DRS1: host key saved to {known_hosts}\n"), out
    assert [(who, result) for who, result, _ in audit(place, "enrol")] == [("EL", "ok")]

    code, out = drs(team.alice, alice, "mt", "status", "DRS1", "--json")
    assert code == 0 and json.loads(out) == {"capsule": "DRS1", "imei": IMEI, "commands": []}, out
    code, out = drs(team.alice, alice, "mt", "resolve", "DRS1", "1", "--not-sent")
    assert (code, out) == (1, "drs: error: no MT command with id 1\n")
