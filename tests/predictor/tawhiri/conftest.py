"""The weather every server test here flies in: DEMO files written once per module around one launch."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest

from predictor.environment.demo_weather import demo_weather_files

LAUNCH = datetime(2024, 5, 1, 6, 0, tzinfo=UTC)
LAUNCH_LAT, LAUNCH_LON = 52.2, -0.4


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return demo_weather_files(LAUNCH_LAT, LAUNCH_LON, LAUNCH, cache_dir=tmp_path_factory.mktemp("wx"))


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> str:
    return str(tmp_path_factory.mktemp("cache"))
