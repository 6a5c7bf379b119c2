"""The demo capsule keeps the firmware's INTERVAL switch-over (the trial saw it switch one cycle early).

The demo world's own report loop runs against the simulated gateway and the console's real MO receiver
on loopback; only the descent path is a short straight line instead of a prediction.
"""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import numpy as np

from console.demo import DemoWorld, Descent
from drs_link.config import MoConfig
from drs_link.iridium.reports import ReportStore
from drs_link.iridium.webhook import MoHttpServer, MoReceiver
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock, generate_test_keys
from drs_link.store import Store
from tests.console.conftest import T0

IMEI = "300434060000010"


def test_the_demo_capsule_switches_interval_on_the_cycle_after_the_download(tmp_path: Path) -> None:
    world = DemoWorld(tmp_path)
    store = Store.open(tmp_path / "drs.sqlite")
    reports = ReportStore(store)
    world.gateway = SimulatedRockblock("drs-demo", "pw", (IMEI,)).start()
    world.jwt_private_key, public = generate_test_keys()  # as DemoWorld.start() signs its deliveries
    key_file = tmp_path / "rockblock-jwt-public.pem"
    key_file.write_text(public)
    mo_config = MoConfig(listen_port=0, jwt_public_key_file=key_file, require_jwt=False)
    world.receiver = MoHttpServer(MoReceiver(reports, mo_config)).start()
    try:
        capsule = SimulatedCapsule(IMEI, 17001)
        path = np.array([0.0, 3600.0])
        descent = Descent(
            capsule, T0, path, np.array([67.9, 67.9]), np.array([21.1, 21.1]), np.array([30000.0, 500.0]),
            (0.0, 0.0), T0 + timedelta(seconds=20),
        )  # fmt: skip
        world._report(descent, T0 + timedelta(minutes=4, seconds=30))  # reports at +0:20, +2:20, +4:20
        form = {"username": "drs-demo", "password": "pw", "imei": IMEI, "data": b"[INTERVAL=5]".hex()}
        assert world.gateway.queue_mt(form).startswith("OK,")
        world._report(descent, T0 + timedelta(minutes=30))
        fixes = [r.report.fix.time for r in reports.for_imei(IMEI) if r.report and r.report.fix]
        spacings = [(b - a).total_seconds() / 60 for a, b in zip(fixes, fixes[1:], strict=False)]
        assert spacings[:6] == [2, 2, 2, 2, 5, 5], "downloaded at 6:20: the 8:20 cycle was armed before it"
    finally:
        world.stop()
        store.close()
