"""Storage parsers (df, /proc/mdstat) and the quoting of every remote command template."""

from __future__ import annotations

import shlex

from hypothesis import given, settings, strategies as st

from drs_link.link import remote
from drs_link.link.storage import parse_df, parse_mdstat

DF = """Filesystem        1-blocks         Used    Available Capacity Mounted on
/dev/md0      127834202112 40000000000 81298292736      33% /mnt/raid1
"""

MDSTAT_HEALTHY = """Personalities : [raid1]
md0 : active raid1 sdd1[3] sdc1[2] sdb1[1] sda1[0]
      124967936 blocks super 1.2 [4/4] [UUUU]
      bitmap: 0/1 pages [0KB], 65536KB chunk

unused devices: <none>
"""

MDSTAT_DEGRADED = """Personalities : [raid1]
md0 : active raid1 sdd1[3](F) sdc1[2] sdb1[1] sda1[0]
      124967936 blocks super 1.2 [4/3] [UUU_]

unused devices: <none>
"""

MDSTAT_INACTIVE = """Personalities : [raid1]
md0 : inactive sdb1[1](S) sda1[0](S)
      249935872 blocks super 1.2

unused devices: <none>
"""


def test_df_gives_bytes_of_the_mount() -> None:
    usage = parse_df(DF)
    assert usage is not None and usage.mount == "/mnt/raid1"
    assert (usage.total_bytes, usage.used_bytes, usage.available_bytes) == (
        127834202112,
        40000000000,
        81298292736,
    )


def test_df_error_output_is_unknown_not_an_exception() -> None:
    assert parse_df("df: /mnt/raid1: No such file or directory\n") is None
    assert parse_df("") is None


def test_mdstat_four_up_is_healthy() -> None:
    raid = parse_mdstat(MDSTAT_HEALTHY)
    assert raid is not None and raid.healthy and raid.state == "healthy" and raid.member_map == "UUUU"


def test_mdstat_with_a_failed_card_is_degraded() -> None:
    raid = parse_mdstat(MDSTAT_DEGRADED)
    assert raid is not None and not raid.healthy and raid.state == "degraded"
    assert (raid.devices_total, raid.devices_up) == (4, 3)


def test_inactive_array_and_missing_array() -> None:
    inactive = parse_mdstat(MDSTAT_INACTIVE)
    assert inactive is not None and inactive.state == "inactive"
    assert parse_mdstat(MDSTAT_HEALTHY, "md1") is None


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=300))
def test_storage_parsers_never_raise(text: str) -> None:
    parse_df(text)
    parse_mdstat(text)


@settings(max_examples=200, deadline=None)
@given(st.text(min_size=1, max_size=60).filter(lambda s: "\x00" not in s))
def test_any_path_is_one_quoted_word_and_round_trips_through_the_label(path: str) -> None:
    command = remote.storage_report(path)
    assert f"-- {shlex.quote(path)};" in command.text
    assert remote.parse_label(command.text) == ("storage", (path,))


def test_holder_outside_the_lock_alphabet_is_rejected_before_reaching_the_pi() -> None:
    for bad in ("EL console", "EL;reboot", "$(id)", ""):
        try:
            remote.power_on("/home/pi/DRS_Python_Tools", "python", bad, 60)
        except ValueError:
            continue
        raise AssertionError(f"holder {bad!r} was accepted")


def test_stock_templates_run_the_flown_script_names() -> None:
    tools, python = "/home/pi/DRS_Python_Tools", "python"
    assert "python DRS_on.py" in remote.power_on(tools, python, "EL@h", 60).text
    assert "python DRS_log_serial.py" in remote.read_serial(tools, python, 0).text
    assert "python DRS_GoGoGo.py" in remote.go(tools, python, "EL@h").text
