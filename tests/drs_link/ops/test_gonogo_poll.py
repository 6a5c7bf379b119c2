"""The go/no-go poll of ARM and FIRE on the server (``OperatorOps.poll_gonogo``): judged on the capsule as
it is when the verdicts are given, however long the "release now" prediction took.

A real simulated capsule over SSH and a real store; the prediction's duration is the test's skipped wall
clock (a first prediction that compiles its kernels on a loaded laptop took 17 s, and the readings
polled before it were 20 s old, STALE, when ARM was judged)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import paramiko

from drs_link.config import parse_config
from drs_link.ops.gonogo import Verdict
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.origin import ReleaseOrigin
from drs_link.ops.staleness import Freshness
from drs_link.ops.telemetry import TelemetryRecord
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store
from tests.clock import SkipClock
from tests.drs_link.conftest import capsule_table

POLLED_ITEMS = ("link", "microcontroller", "gnss")


def test_a_slow_prediction_leaves_no_polled_reading_stale(
    tmp_path: Path,
    make_sim: Callable[..., CapsuleSimulator],
    client_key: tuple[Path, paramiko.PKey],
    skip_clock: SkipClock,
) -> None:
    sim = make_sim()
    known_hosts = tmp_path / "known_hosts"
    known_hosts.write_text(sim.known_hosts_line())
    capsule = capsule_table(sim, client_key[0], known_hosts=str(known_hosts))
    config = parse_config(
        {"operator": {"name": "EL"}, "data": {"dir": str(tmp_path / "data")}, "capsule": [capsule]}
    )
    ops = OperatorOps(config, Store.open(config.store_path))
    try:
        ops.links.power_on(sim.name)
        ops.state.ops(sim.name).machine.wait_for_microcontroller()
        origins: list[ReleaseOrigin] = []

        def slow_prediction(name: str, origin: ReleaseOrigin) -> list[TelemetryRecord]:
            origins.append(origin)
            skip_clock.skip(60.0)  # three times as long as a polled reading stays fresh (20 s)
            return []

        report = ops.release.poll_gonogo(sim.name, slow_prediction)
    finally:
        ops.close()
    assert origins, "the prediction ran from the polled fix"
    judged = {item.key: item for item in report.items}
    for key in POLLED_ITEMS:
        assert Freshness.STALE.value.upper() not in judged[key].detail, judged[key]
        assert judged[key].verdict is Verdict.GO, judged[key]
