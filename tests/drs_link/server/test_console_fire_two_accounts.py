"""The console's FIRE under `require_second_operator` through a real shared `drs server`: the capsule
simulator behind a real sshd, real accounts. The console (this test's process, root, listed as operator
RT) acts only through the server, so the server refuses it alone however it asks; another account's
`drs approve` releases the capsule once, and the console's `c` withdraws a request nobody may then approve."""

from __future__ import annotations

import json
import os
import pwd
from collections.abc import Iterator
from pathlib import Path

import pytest

from console.context import ConsoleSetup
from drs_link.config import load_config
from drs_link.errors import RefusedError
from drs_link.ops import OperatorOps
from drs_link.server.protocol import Second
from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import write_ed25519
from drs_link.store import Store
from tests.console.conftest import ConsoleUnderTest, wait_for
from tests.drs_link.conftest import SIM_SCALE, capsule_table
from tests.drs_link.server.team import Server, Team, client_config, drs, needs_root, server_config
from tests.release_helpers import ROCKBLOCK_PASSWORD_ENV, ROCKBLOCK_TOML, SYNC_WAIVER, write_weather

pytestmark = [needs_root, pytest.mark.slow, pytest.mark.asyncio]


@pytest.fixture
def console(
    place: Path, team: Team, monkeypatch: pytest.MonkeyPatch
) -> Iterator[tuple[CapsuleSimulator, ConsoleUnderTest]]:
    """A powered capsule, the team's server (the rule on, a 120 s window, root listed as RT), and a
    console of root's whose own configuration names the server's socket."""
    key = place / "keys" / "id_ed25519"
    sim = CapsuleSimulator(authorized_keys=[write_ed25519(key)], clock_scale=SIM_SCALE)
    sim.start()
    server = None
    try:
        known_hosts = place / "known_hosts"
        known_hosts.write_text(sim.known_hosts_line())
        table = capsule_table(sim, key, known_hosts=str(known_hosts), python="python3")
        capsule = "\n".join(f"{k} = {json.dumps(v)}" for k, v in table.items())
        rule = f"[console]\nrequire_second_operator = true\narm_window_s = 120.0\n[[capsule]]\n{capsule}\n"
        body = f'[[operator]]\naccount = "root"\nname = "RT"\n{ROCKBLOCK_TOML}{rule}'
        config = server_config(place, team, body)
        setup = place / "root.toml"  # root powers the capsule on first, on the server's store
        setup.write_text(config.read_text().split("[[operator]]")[0].replace("[data]", '[operator]\nname = "RT"\n[data]')
                         + ROCKBLOCK_TOML + rule)  # fmt: skip
        from console.commands.main import main

        assert main(["--config", str(setup), "capsule", "power-on", "DRS1", "--yes"]) == 0
        server = Server(config, place, team.group, {ROCKBLOCK_PASSWORD_ENV: "pw"})
        mine = client_config(
            place, "root", f'[data]\ndir = "{place / "console-data"}"\n{ROCKBLOCK_TOML}{rule}'
        )
        own = load_config(mine)
        store = Store.open(own.store_path)
        operations = OperatorOps(own, store, environ={ROCKBLOCK_PASSWORD_ENV: "pw"})
        weather = place / "gfs"
        weather.mkdir()
        app = ConsoleUnderTest(ConsoleSetup(
            mode="live", capsules=["DRS1"], server=server.socket, weather=tuple(write_weather(weather)),
        ), store, operations)  # fmt: skip
        # The console's own poll of go/no-go (no predictions here) must not close the window under test:
        # FIRE polls again on the server, with the weather.
        monkeypatch.setattr(app, "watch_arming", lambda capsules, links_lost: None)
        app.context.waive("DRS1", "sync", SYNC_WAIVER)  # as `w` does: held by the server for ARM and FIRE
        yield sim, app
    finally:
        if server is not None:
            server.stop()
        sim.stop()


def armed(app: ConsoleUnderTest) -> bool:
    state = app.context.arm_state("DRS1")
    return state is not None and state.state == "armed" and state.mine


async def test_the_consoles_fire_is_refused_alone_and_released_by_another_accounts_drs_approve(
    console: tuple[CapsuleSimulator, ConsoleUnderTest], place: Path, team: Team
) -> None:
    sim, app = console
    bob = client_config(place, team.bob)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "a")
        await wait_for(pilot, lambda: armed(app))
        with pytest.raises(RefusedError, match="a typed second operator is not accepted"):
            app.context.fire("DRS1", "DRS1", Second(name="JM"), lambda pending: None)
        with pytest.raises(RefusedError, match="a single-operator waiver is not accepted"):
            app.context.fire("DRS1", "DRS1", Second(waiver="alone on the ice"), lambda pending: None)
        with pytest.raises(RefusedError, match="a second login's approval is needed"):
            app.context.fire("DRS1", "DRS1", Second(), lambda pending: None)
        await pilot.press("f", *"DRS1")
        await pilot.click("#approval")
        await wait_for(pilot, lambda: bool(app.context.waiting_approvals("DRS1")))
        [request] = app.context.waiting_approvals("DRS1")
        with pytest.raises(RefusedError, match="cannot approve it"):
            app.context.decide(request.id, True, "")  # the requester's own account, from its own console
        assert sim.firmware.go_at is None, "nothing is sent while the request waits"
        code, out = drs(team.bob, bob, "approve", str(request.id))
        assert code == 0, out
        await wait_for(pilot, lambda: sim.firmware.go_at is not None)
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "fired")
    store = Store.open(place / "state" / "drs.sqlite")
    [fire] = [a for a in store.audit("DRS1") if a.action == "fire" and a.result == "authorised"]
    assert fire.detail is not None and fire.detail["approved_by"].startswith(f"JM ({team.bob})")
    uids = [a.detail["uid"] for a in store.audit("DRS1") if a.action == "approval.peer" and a.detail]
    assert uids == [os.geteuid(), pwd.getpwnam(team.bob).pw_uid]
    assert [a.result for a in store.audit("DRS1") if a.action == "go"] == [
        "sending",
        "released, Pi shut down",
    ]


async def test_c_withdraws_the_consoles_waiting_request_and_nobody_can_approve_it_after(
    console: tuple[CapsuleSimulator, ConsoleUnderTest], place: Path, team: Team
) -> None:
    """#23: the waiting request is a live line with its own countdown, and `c` cancels it (the console
    drops the FIRE's connection; the server withdraws the request it waited on)."""
    sim, app = console
    bob = client_config(place, team.bob)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter")
        screen = app.screen
        assert screen.check_action("cancel_approval", ()) is False, "nothing waits: no cancel key"
        await pilot.press("a")
        await wait_for(pilot, lambda: armed(app))
        await pilot.press("f", *"DRS1")
        await pilot.click("#approval")
        await wait_for(pilot, lambda: bool(app.context.waiting_approvals("DRS1")))
        [request] = app.context.waiting_approvals("DRS1")
        line = screen.query_one("#arm-status")
        await wait_for(pilot, lambda: f"approval #{request.id}" in str(line.render()))
        first = str(line.render())
        assert "s left · c cancels" in first and screen.check_action("cancel_approval", ()) is True
        await wait_for(pilot, lambda: str(line.render()) != first)  # its own countdown runs
        await pilot.press("c")
        await wait_for(pilot, lambda: any(f"approval #{request.id} cancelled" in n.message
                                          for n in app._notifications))  # fmt: skip
        await wait_for(pilot, lambda: f"approval #{request.id}" not in str(line.render()))
        code, out = drs(team.bob, bob, "approve", str(request.id))
        assert code == 1 and "is cancelled" in out, out
        assert sim.firmware.go_at is None
    store = Store.open(place / "state" / "drs.sqlite")
    assert [a.result for a in store.audit("DRS1") if a.action == "approval.cancelled"] == ["cancelled"]
