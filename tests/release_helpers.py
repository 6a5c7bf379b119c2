"""What a release needs from a terminal test: weather over the simulator's sky, a gateway and a waiver.

``drs capsule arm``/``go`` run the console's go/no-go poll: the landing prediction needs weather
covering now over Esrange (the simulator's GNSS), the gateway item a configured RockBLOCK account, and
the sync item (nothing is synced in these setups) a waiver with a reason.
"""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import numpy as np

from drs_link.store import utc_now
from predictor.environment.gribwrite import gfs_file_name, write_gfs_grib2
from tests.predictor.predict_helpers import H_ISO, LEVELS_HPA, P0_HPA, T_ISO

ROCKBLOCK_PASSWORD_ENV = "DRS_GO_RB"
ROCKBLOCK_TOML = (
    f'[rockblock]\nmt_url = "http://127.0.0.1:9/rockblock/MT"\nusername = "ops"\n'
    f'password_env = "{ROCKBLOCK_PASSWORD_ENV}"\n'
)
SYNC_WAIVER = "the ground copy holds the rest"
WAIVE_SYNC = ("--waive", f"sync={SYNC_WAIVER}")


def write_weather(root: Path) -> list[Path]:
    """GFS files written by eccodes over Esrange for the cycle around now (steps 0-9 h), a steady wind."""
    now = utc_now()
    cycle = now.replace(minute=0, second=0, microsecond=0) - timedelta(hours=now.hour % 6)
    lats, lons = np.arange(64.0, 71.01, 0.5), np.arange(16.0, 27.01, 0.5)
    shape = (LEVELS_HPA.size, lats.size, lons.size)
    gh = np.broadcast_to((-H_ISO * np.log(LEVELS_HPA / P0_HPA))[:, None, None], shape)
    return [
        write_gfs_grib2(root / gfs_file_name(cycle, step), cycle, step, LEVELS_HPA, lats, lons,
                        np.full(shape, 8.0), np.full(shape, 2.0), np.full(shape, T_ISO), gh)
        for step in (0, 3, 6, 9)
    ]  # fmt: skip


def release_args(weather: list[Path]) -> list[str]:
    """What `drs capsule arm` and `drs capsule go` both take: the weather and the sync waiver."""
    return ["--weather", *map(str, weather), *WAIVE_SYNC]
