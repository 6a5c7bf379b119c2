"""``drs capsule bench``: measured link numbers against a capsule simulator on loopback.

Unit tests never time anything; this command does, so README numbers come from a run anyone can
repeat. Loopback against the paramiko simulator measures the console's own overhead (handshake,
host-key check, command round trip, SFTP + on-Pi sha256 verification), not the gondola Wi-Fi.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from drs_link.config import CapsuleConfig, parse_config
from drs_link.link import CapsuleLink, Syncer
from drs_link.link.backends import build_backend
from drs_link.ops import ReleaseStateMachine
from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import write_ed25519
from drs_link.store import Store


@dataclass(frozen=True)
class BenchResult:
    connect_ms_median: float
    heartbeat_ms_median: float
    heartbeat_ms_p95: float
    sync_mb: float
    sync_mb_per_s: float
    release_wall_s: float
    release_sim_s: float
    clock_scale: float


def _config(sim: CapsuleSimulator, key: Path, known_hosts: Path) -> CapsuleConfig:
    known_hosts.write_text(sim.known_hosts_line())
    table = {
        "name": sim.name,
        "host": "127.0.0.1",
        "port": sim.port,
        "identity_file": str(key),
        "known_hosts": str(known_hosts),
        "python": "python3",
    }
    return parse_config({"capsule": [table]}).capsules[0]


def run_bench(sync_mb: float = 32.0, rounds: int = 20, clock_scale: float = 40.0) -> BenchResult:
    with tempfile.TemporaryDirectory(prefix="drs-bench-") as tmp:
        root = Path(tmp)
        key = write_ed25519(root / "id_ed25519")
        with CapsuleSimulator("BENCH", [key], clock_scale=clock_scale) as sim:
            config = _config(sim, root / "id_ed25519", root / "known_hosts")
            connects = []
            for _ in range(max(3, rounds // 4)):
                link = CapsuleLink(config)
                start = time.perf_counter()
                link.connect()
                connects.append((time.perf_counter() - start) * 1000)
                link.close()
            link = CapsuleLink(config)
            link.connect()
            beats = []
            for _ in range(rounds):
                start = time.perf_counter()
                if not link.heartbeat():
                    raise RuntimeError("heartbeat failed against the local simulator")
                beats.append((time.perf_counter() - start) * 1000)
            source = root / "payload"
            source.mkdir()
            (source / "data.bin").write_bytes(os.urandom(int(sync_mb * 1024 * 1024)))
            syncer = Syncer(Store.open(root / "drs.sqlite"), link, sim.name, config.storage_mount)
            start = time.perf_counter()
            report = syncer.sync(source)
            sync_s = time.perf_counter() - start
            machine = ReleaseStateMachine(
                Store.open(root / "drs.sqlite"),
                config,
                build_backend(config, link),
                "bench",
                clock=sim.clock.now,
                sleep=sim.clock.sleep,
            )
            sim_start = sim.clock.now()
            start = time.perf_counter()
            machine.power_on(confirmed=True)
            machine.wait_for_microcontroller()
            machine.go(machine.confirm(sim.name))
            release_s = time.perf_counter() - start
            release_sim_s = (sim.clock.now() - sim_start).total_seconds()
            link.close()
    beats.sort()
    return BenchResult(
        connect_ms_median=statistics.median(connects),
        heartbeat_ms_median=statistics.median(beats),
        heartbeat_ms_p95=beats[min(len(beats) - 1, int(0.95 * len(beats)))],
        sync_mb=report.bytes_sent / 1024 / 1024,
        sync_mb_per_s=report.bytes_sent / 1024 / 1024 / sync_s,
        release_wall_s=release_s,
        release_sim_s=release_sim_s,
        clock_scale=clock_scale,
    )
