"""Exports are created 0640, for the owner and its group, whatever the umask (#16: they were 0644).

The umask is cleared here so that a mode coming from it, not from the code, would show.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.iridium.track_export import export_track
from predictor.geofiles.output import write_text
from tests.drs_link.iridium.flight_logs import flight_reports


@pytest.fixture
def no_umask() -> Iterator[None]:
    old = os.umask(0)
    try:
        yield
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


@pytest.mark.usefixtures("no_umask")
def test_a_written_export_is_for_its_owner_and_group_only(tmp_path: Path) -> None:
    assert _mode(write_text(tmp_path / "landing.kml", "<kml/>", "KML")) == 0o640


@pytest.mark.usefixtures("no_umask")
def test_a_track_export_is_for_its_owner_and_group_only(tmp_path: Path, shared_data: Path) -> None:
    reports = flight_reports(shared_data / "tracks" / "pyballoon_superbit" / "19-1-1.csv")
    assert _mode(export_track(reports, tmp_path / "track.csv", "DRS1").path) == 0o640
