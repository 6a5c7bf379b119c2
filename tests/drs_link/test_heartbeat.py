"""The link monitor against the simulated capsule: DOWN after missed heartbeats, UP again after."""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest

from drs_link.config import CapsuleConfig
from drs_link.heartbeat import LinkMonitor, LinkState, LinkStatus
from drs_link.simulator import CapsuleSimulator
from drs_link.ssh import CapsuleLink

pytestmark = pytest.mark.slow


def test_missed_heartbeats_mark_the_link_down_with_backoff_then_up_again(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    config = sim_config(sim, connect_timeout_s=1.0)
    changes: list[LinkStatus] = []
    link = CapsuleLink(config, sleep=lambda _: None)
    monitor = LinkMonitor(
        link,
        interval_s=1.0,
        heartbeat_timeout_s=0.3,
        failures_to_down=2,
        max_backoff_s=4.0,
        on_change=changes.append,
    )
    assert monitor.beat().state is LinkState.UP
    sim.faults.response_delay_s = 1.0
    assert monitor.beat().state is LinkState.UP and monitor.status().consecutive_failures == 1
    down = monitor.beat()
    assert down.state is LinkState.DOWN and down.next_try_in_s == 2.0
    assert monitor.beat().next_try_in_s == 4.0 and monitor.beat().next_try_in_s == 4.0
    sim.faults.response_delay_s = 0.0
    up = monitor.beat()
    assert up.state is LinkState.UP and up.consecutive_failures == 0 and up.next_try_in_s == 1.0
    assert [c.state for c in changes] == [LinkState.UP, LinkState.DOWN, LinkState.UP]
    monitor.stop()


def test_monitor_thread_starts_and_stops_cleanly(
    make_sim: Callable[..., CapsuleSimulator], sim_config: Callable[..., CapsuleConfig]
) -> None:
    sim = make_sim()
    seen: list[LinkStatus] = []
    monitor = LinkMonitor(CapsuleLink(sim_config(sim)), interval_s=0.05, on_change=seen.append)
    monitor.start()
    deadline = time.monotonic() + 5
    while not seen and time.monotonic() < deadline:
        time.sleep(0.02)
    monitor.stop()
    assert seen and seen[0].state is LinkState.UP
