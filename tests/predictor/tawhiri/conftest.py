"""The weather every server test here flies in (DEMO files written once per module around one launch),
and the server the command line builds on it."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import pytest

from console.commands.main import build_parser
from console.commands.serve import build_server
from predictor.environment.demo_weather import demo_weather_files
from predictor.tawhiri import ApiServer

LAUNCH = datetime(2024, 5, 1, 6, 0, tzinfo=UTC)
LAUNCH_LAT, LAUNCH_LON = 52.2, -0.4


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return demo_weather_files(LAUNCH_LAT, LAUNCH_LON, LAUNCH, cache_dir=tmp_path_factory.mktemp("wx"))


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> str:
    return str(tmp_path_factory.mktemp("cache"))


@pytest.fixture(scope="module")
def server(weather: list[Path], cache: str) -> Iterator[ApiServer]:
    argv = ["serve", "predictor", "--port", "0", "--weather", *map(str, weather), "--cache-dir", cache]
    api = build_server(build_parser("serve").parse_args(argv))
    thread = threading.Thread(target=api.serve_forever, daemon=True)
    thread.start()
    yield api
    api.shutdown()
    api.server_close()
    thread.join(timeout=5)
