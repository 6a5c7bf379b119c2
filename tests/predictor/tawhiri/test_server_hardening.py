"""`drs serve predictor` against hostile and careless clients, over real sockets on loopback (#31 item 3).

Each test here failed on main at 3837fc8: ``ascent_rate=5_0`` was flown as 50 m/s and ``٥`` as 5,
``descent_rate=1e-300`` generated hours of weather before it failed, /health was 404, HEAD 501, a
client leaving early printed a traceback, 32 idle sockets locked every other client out, a bad GRIB
file in ``--weather-dir`` made every request a 404, and nothing was loaded before the ready line.
"""

from __future__ import annotations

import http.client
import json
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from console.commands.main import build_parser
from console.commands.serve import build_server
from predictor.tawhiri import ApiServer, server as http_server
from tests.ports import free_port
from tests.predictor.tawhiri.test_tawhiri_api import chasemapper_query, get, get_with_headers


@pytest.mark.parametrize(
    "text",
    ["5_0", "٥", "５", "5\u00a0", " 5", "inf", "nan", "0x10", "5.0.0", "1e999", "+", ".", "9" * 5000],
)
def test_a_number_outside_a_urls_grammar_is_refused(server: ApiServer, text: str) -> None:
    """Python's float reads 5_0 as 50, ٥ and ５ as 5, and strips spaces; a URL's number is ASCII digits,
    a sign, a point and an exponent. A 5,000-digit number is refused before Python converts it."""
    status, _, body = get(server, chasemapper_query(ascent_rate=text))
    error = json.loads(body)["error"]
    assert status == 400 and error["type"] == "RequestException", body
    assert "'ascent_rate'" in error["description"] and len(error["description"]) < 300


@pytest.mark.parametrize("text", ["5", "+5", "5.", ".5e1", "5E0", "0.5e+1", "50e-1"])
def test_a_number_in_the_grammar_is_read(server: ApiServer, text: str) -> None:
    status, _, body = get(
        server, chasemapper_query(ascent_rate=text, launch_altitude=12000, burst_altitude=12001)
    )
    assert status == 200 and json.loads(body)["request"]["ascent_rate"] == 5.0


REFUSALS: list[tuple[dict[str, Any], str]] = [
    ({"descent_rate": "1e-300"}, "descent_rate"),
    ({"ascent_rate": "1e-300"}, "ascent_rate"),
    ({"descent_rate": "0.2"}, "descent_rate"),  # raised to nothing: 14 h from 30 km
    ({"launch_altitude": "1e6", "burst_altitude": "1e6"}, "launch_altitude"),
    ({"launch_altitude": "-1e6"}, "launch_altitude"),
    ({"burst_altitude": "1e9"}, "burst_altitude"),
    ({"launch_datetime": "9999-01-01T00:00:00Z"}, "launch_datetime"),
    ({"launch_datetime": "1900-01-01T00:00:00Z"}, "launch_datetime"),
    ({"launch_datetime": "2024-05-01T06:00:00\u0665Z"}, "launch_datetime"),
    (
        {"profile": "float_profile", "float_altitude": 30000, "stop_datetime": "2024-06-01T00:00:00Z"},
        "stop_datetime",
    ),
    (
        {"profile": "float_profile", "float_altitude": 30000, "stop_datetime": "2024-05-01T05:00:00Z"},
        "stop_datetime",
    ),
    ({"profile": "reverse_profile", "launch_altitude": 30000, "ascent_rate": "0.3"}, "ascent_rate"),
]
"""A rate, altitude or time no flight has, and the parameter the refusal must name."""


class TestRefusedBeforeAnyWeatherIsMade:
    """With DEMO weather every request once generated its own files first: 1e-300 was a 500 after 7 s.
    One demo server answers them all (a server each cost 2-4 s to start); every request is checked
    to have added no file to its directories."""

    @pytest.fixture(scope="class")
    def demo(self, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[ApiServer, Path]]:
        root = tmp_path_factory.mktemp("demo-serve")
        with pytest.MonkeyPatch.context() as env:
            env.setenv("XDG_CACHE_HOME", str(root / "xdg"))
            argv = ["serve", "predictor", "--port", "0", "--demo-weather", "--cache-dir", str(root / "cache")]
            server = build_server(build_parser("serve").parse_args(argv))
            thread = threading.Thread(target=server.serve_forever, daemon=True)
            thread.start()
            try:
                yield server, root
            finally:
                server.shutdown()
                server.server_close()

    @pytest.mark.parametrize(("changes", "named"), REFUSALS)
    def test_a_rate_altitude_or_time_no_flight_has_is_refused_before_any_weather_is_made(
        self, demo: tuple[ApiServer, Path], changes: dict[str, Any], named: str
    ) -> None:
        server, root = demo
        made = sorted(p for p in root.rglob("*") if p.is_file())
        status, _, body = get(server, chasemapper_query(**changes))
        error = json.loads(body)["error"]
        assert (status, error["type"]) == (400, "RequestException"), body
        assert f"'{named}'" in error["description"]
        assert sorted(p for p in root.rglob("*") if p.is_file()) == made, "no weather was made for it"


def test_health_says_the_weather_is_loaded_the_code_warm_and_the_version(server: ApiServer) -> None:
    with urllib.request.urlopen(server.url.replace("/api/v1/", "/health"), timeout=10) as response:
        assert response.status == 200 and response.headers["Content-Type"] == "application/json"
        health = json.loads(response.read())
    assert health["status"] == "ok" and health["warm"] is True and health["warmed_in_s"] > 0
    assert re.fullmatch(r"\d+\.\d+\.\d+.*", health["version"])
    weather = health["weather"]
    assert weather["loaded"] is True and weather["kind"] == "files" and weather["is_demo"] is True
    assert weather["dataset"] == "2024-05-01T06:00:00Z" and weather["valid_from"] <= weather["valid_to"]


def test_head_answers_as_get_without_a_body(server: ApiServer) -> None:
    status, kind, body, headers = get_with_headers(server, chasemapper_query())
    host, port = server.server_address[:2]
    for path, expected in (
        (f"/api/v1/?{urllib.parse.urlencode(chasemapper_query())}", (status, kind, len(body))),
        ("/health", None),
        ("/api/v1/?ascent_rate=5_0", None),
    ):
        connection = http.client.HTTPConnection(str(host), int(port), timeout=60)
        connection.request("HEAD", path)
        response = connection.getresponse()
        assert response.read() == b"", "HEAD has no body"
        length = int(response.headers["Content-Length"])
        connection.close()
        if expected is not None:
            assert (response.status, response.headers["Content-Type"], length) == expected
        else:
            assert response.status in (200, 400) and length > 0
    assert headers["Content-Length"] == str(len(body))


def test_idle_sockets_cannot_lock_another_client_out(
    server: ApiServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    """40 idle connections from one address hold at most MAX_PER_CLIENT threads; a client at another
    address (the chase car's laptop) is answered while they idle, and the idle ones are closed after
    REQUEST_READ_S."""
    host, port = server.server_address[:2]
    idle = [socket.create_connection((str(host), int(port)), timeout=30) for _ in range(40)]
    try:
        time.sleep(0.5)  # every one accepted and holding its slot (or told 503)
        other = http.client.HTTPConnection(str(host), int(port), timeout=30, source_address=("127.0.0.2", 0))
        other.request("GET", f"/api/v1/?{urllib.parse.urlencode(chasemapper_query())}")
        response = other.getresponse()
        assert response.status == 200 and json.loads(response.read())["prediction"]
        other.close()
        began = time.monotonic()
        answers = [sock.recv(4096) for sock in idle]
        waited = time.monotonic() - began
        busy = [a for a in answers if a.startswith(b"HTTP/1.0 503")]
        assert len(busy) == 40 - http_server.MAX_PER_CLIENT, "beyond the per-client limit: 503 at once"
        assert answers.count(b"") == http_server.MAX_PER_CLIENT, "the idle ones are closed"
        assert waited < http_server.REQUEST_READ_S + 10, "closed after the idle timeout, not held"
    finally:
        for sock in idle:
            sock.close()


def _drs(*argv: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "console.commands.main", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip


def _ready(process: subprocess.Popen[str], port: int) -> str:
    """The log up to and with the ready line."""
    assert process.stderr is not None
    said = ""
    for line in process.stderr:
        said += line
        if "Tawhiri v1 API at" in line:
            assert f"http://127.0.0.1:{port}/api/v1/" in line
            return said
        assert "Traceback" not in line, line
    raise AssertionError(f"no ready line; exit {process.wait(timeout=30)}")


def _stop(process: subprocess.Popen[str]) -> str:
    process.send_signal(signal.SIGTERM)
    assert process.wait(timeout=60) == 0
    assert process.stderr is not None
    return process.stderr.read()


def test_the_ready_line_comes_after_the_weather_is_loaded_and_the_code_is_warm(
    weather: list[Path], tmp_path: Path
) -> None:
    """The first request after the ready line once took 9.2-21.6 s (decoding, compiling); chasemapper gives
    up after 10 s. Now /health at the ready line already says loaded and warm (the time to the first
    answer is measured by tools/serve_first_answer.py, not here)."""
    port = free_port()
    server = _drs("serve", "predictor", "--port", str(port), "--weather", *map(str, weather),
                  "--cache-dir", str(tmp_path / "cache"))  # fmt: skip
    try:
        assert "weather loaded and compiled code warm in" in _ready(server, port).splitlines()[-1]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as response:
            health = json.loads(response.read())
        assert health["status"] == "ok" and health["warm"] is True and health["weather"]["loaded"] is True
        query = urllib.parse.urlencode(chasemapper_query())
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/v1/?{query}", timeout=60) as response:
            assert response.status == 200
        _stop(server)
    finally:
        server.kill()


def test_a_client_leaving_before_its_answer_is_one_log_line(weather: list[Path], tmp_path: Path) -> None:
    """A reset connection (SO_LINGER 0) before the answer: one line per client in the log, no traceback."""
    port = free_port()
    server = _drs("serve", "predictor", "--port", str(port), "--weather", *map(str, weather),
                  "--cache-dir", str(tmp_path / "cache"))  # fmt: skip
    try:
        _ready(server, port)
        query = urllib.parse.urlencode(chasemapper_query(format="kml"))
        for _ in range(5):
            client = socket.create_connection(("127.0.0.1", port), timeout=10)
            client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            client.sendall(f"GET /api/v1/?{query} HTTP/1.0\r\n\r\n".encode())
            client.close()  # a reset: the server's answer meets a closed socket
        time.sleep(2.0)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/v1/?{query}", timeout=60) as response:
            assert response.status == 200, "still serving"
        log = _stop(server)
    finally:
        server.kill()
    assert "Traceback" not in log, log
    assert log.count("left before its answer was sent") == 5, log


def test_a_bad_grib_file_in_the_weather_dir_is_refused_and_the_others_served(
    weather: list[Path], tmp_path: Path
) -> None:
    """A truncated file and a garbage .grib2 beside good ones: the process starts, names both on /health,
    and answers from the good ones; one more bad file dropped in while it serves changes nothing."""
    directory = tmp_path / "gfs"
    directory.mkdir()
    for file in weather:
        (directory / file.name).write_bytes(file.read_bytes())
    good = weather[0].read_bytes()
    (directory / "gfs.t06z.pgrb2.0p50.f099.grib2").write_bytes(good[: len(good) // 2])
    (directory / "garbage.grib2").write_bytes(b"GRIB" + bytes(range(256)) * 40)
    port = free_port()
    server = _drs("serve", "predictor", "--port", str(port), "--weather-dir", str(directory),
                  "--cache-dir", str(tmp_path / "cache"))  # fmt: skip
    try:
        started = _ready(server, port)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as response:
            health = json.loads(response.read())
        refused = " ".join(health["weather"]["refused"])
        assert health["status"] == "ok" and "garbage.grib2" in refused and "f099" in refused, health
        query = urllib.parse.urlencode(chasemapper_query())
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/v1/?{query}", timeout=120) as response:
            assert response.status == 200
        (directory / "later.grib2").write_bytes(b"GRIB\x00\x00\x00\x02" + b"\xff" * 5000)
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/api/v1/?{query}", timeout=120) as response:
            assert response.status == 200
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as response:
            assert "later.grib2" in " ".join(json.loads(response.read())["weather"]["refused"])
        assert server.poll() is None, "the server is still running"
        log = started + _stop(server)
    finally:
        server.kill()
    assert "Traceback" not in log
    assert log.count("weather file refused") == 3, log


def test_post_to_health_is_refused(server: ApiServer) -> None:
    request = urllib.request.Request(server.url.replace("/api/v1/", "/health"), data=b"x", method="POST")
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=10)
    assert refused.value.code == 405 and refused.value.headers["Allow"] == "GET, HEAD"
