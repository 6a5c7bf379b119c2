"""A simulated descent end to end: capsule → gateway → signed webhook → store → lifecycle → PARACHUTE."""

from __future__ import annotations

import time
from datetime import timedelta
from pathlib import Path

from drs_link.config import CapsuleConfig, MoConfig
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.parachute import plan_parachute
from drs_link.iridium.recovery import detect_landing, distance_bearing, track_from_reports
from drs_link.iridium.reports import ReportStore, StoredReport
from drs_link.iridium.webhook import MoHttpServer, MoReceiver
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock, generate_test_keys, post_mo
from drs_link.store import Store

from .helpers import IMEI, T0, fix_at


def test_descent_landing_and_parachute_release_through_every_part(tmp_path: Path) -> None:
    private, public = generate_test_keys()
    key_file = tmp_path / "rock7.pem"
    key_file.write_text(public)
    store = Store.open(tmp_path / "drs.sqlite")
    reports = ReportStore(store)
    clock_now = [T0]
    life = lc.CommandLifecycle(store, "alice", lambda: clock_now[0])

    def after_answer(stored: StoredReport) -> None:
        life.observe(reports.for_imei(stored.delivery.imei), stored.delivery.imei)

    config = MoConfig(listen_host="127.0.0.1", listen_port=0, jwt_public_key_file=key_file, require_jwt=True)
    server = MoHttpServer(MoReceiver(reports, config, after_answer)).start()
    gateway = SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)).start()
    try:
        capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
        client = RockblockGateway(gateway.url, "ops", "pw", timeout_s=2, retry_delay_s=0)
        alarm = T0
        site = (46.53, 6.71)
        for cycle in range(10):
            falling = cycle < 6
            alt = 24000 - 4500 * cycle if falling else 612
            lat = site[0] - 0.01 * (6 - cycle) if falling else site[0] + 0.00002 * (-1) ** cycle
            fix_time = alarm + timedelta(seconds=20 + 7 * (cycle % 3))
            fix = fix_at(fix_time, lat=lat, lon=site[1], alt=alt, speed=9.0 if falling else 0.1)
            delivery = capsule.session(gateway, fix, fix_time + timedelta(seconds=35), (lat, site[1], 4.0))
            assert post_mo(server.url, delivery, jwt_private_key=private) == 200
            alarm = capsule.next_cycle(alarm)
        stored = reports.for_imei(IMEI)
        landing = detect_landing(track_from_reports(stored))
        assert landing is not None and distance_bearing(site[0], site[1], landing.lat, landing.lon)[0] < 5

        clock_now[0] = stored[-1].time + timedelta(seconds=40)
        plan = plan_parachute(stored, clock_now[0], life.for_imei(IMEI))
        message = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).add("SOUNDER", False).build()
        capsule_config = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=IMEI)
        command = life.send(life.request(capsule_config, message).id, "DRS1", client)
        assert command.state == lc.QUEUED

        # Planned 40 s after the fix, the next cycle's queue-before would leave the operator less than
        # OPERATOR_MARGIN, so the plan aims at the cycle after it; its HH:MM is accepted a window wide,
        # so the capsule's very next session, which downloads the queued MT, opens the parachute.
        assert plan.cycles[0].offset == 2
        fix_time = alarm + timedelta(seconds=27)
        delivery = capsule.session(gateway, fix_at(fix_time, lat=site[0], lon=site[1], alt=612), fix_time)
        assert capsule.parachute_open and not capsule.sounder_on
        assert post_mo(server.url, delivery, jwt_private_key=private) == 200
        deadline = time.monotonic() + 10
        while life.get(command.id).state == lc.QUEUED and time.monotonic() < deadline:
            time.sleep(0.02)
        assert life.get(command.id).state == lc.UNCONFIRMABLE
    finally:
        gateway.stop()
        server.stop()
        store.close()
