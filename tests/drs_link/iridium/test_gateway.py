"""The RockBLOCK MT client against a real HTTP server on 127.0.0.1 (the simulated gateway)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from keyring.backend import KeyringBackend

from drs_link.config import RockblockConfig
from drs_link.errors import ConfigError
from drs_link.iridium.gateway import FAILURE_MEANINGS, RockblockGateway, resolve_password
from drs_link.sim.rockblock import Scripted, SimulatedRockblock
from tests.ports import free_port

IMEI = "300234010753370"
SECRET = "s3cret-pass"


@pytest.fixture
def rockblock() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password=SECRET, imeis=(IMEI,)) as gateway:
        yield gateway


def client(url: str, timeout_s: float = 2.0, **kwargs: object) -> RockblockGateway:
    return RockblockGateway(url, "ops", SECRET, timeout_s=timeout_s, retry_delay_s=0.0, **kwargs)  # type: ignore[arg-type]


def test_ok_reply_gives_the_mt_id_and_credentials_travel_only_in_the_body(
    rockblock: SimulatedRockblock,
) -> None:
    result = client(rockblock.url).send(IMEI, b"[INTERVAL=5]")
    assert (result.status, result.mt_id) == ("queued", 4114652)
    [request] = rockblock.requests
    assert request.path == "/rockblock/MT"
    assert request.form == {
        "imei": IMEI,
        "username": "ops",
        "password": SECRET,
        "data": "5B494E54455256414C3D355D",
    }
    assert list(rockblock.queues[IMEI]) == [b"[INTERVAL=5]"]


@pytest.mark.parametrize("code", sorted(FAILURE_MEANINGS))
def test_each_documented_failure_code_is_reported_with_its_meaning(
    rockblock: SimulatedRockblock, code: int
) -> None:
    rockblock.script(Scripted("failed", code=code))
    result = client(rockblock.url).send(IMEI, b"[SOUNDER_OFF]")
    assert (result.status, result.code) == ("failed", code)
    assert FAILURE_MEANINGS[code] in result.detail
    assert not result.may_be_queued
    assert len(rockblock.requests) == 1


def test_wrong_password_and_unknown_imei_are_the_gateways_own_failures(rockblock: SimulatedRockblock) -> None:
    wrong = RockblockGateway(rockblock.url, "ops", "nope", retry_delay_s=0.0).send(IMEI, b"[SOUNDER_OFF]")
    assert wrong.code == 10 and "nope" not in wrong.detail
    assert client(rockblock.url).send("300234010000000", b"[SOUNDER_OFF]").code == 11


def test_timeout_after_the_request_was_written_is_unknown_and_never_sent_twice(
    rockblock: SimulatedRockblock,
) -> None:
    rockblock.script(Scripted("slow", delay_s=1.5))
    result = client(rockblock.url, timeout_s=0.5).send(IMEI, b"[PARACHUTE=14:05]")
    assert result.status == "unknown" and result.may_be_queued
    assert "NOT re-sent" in result.detail
    assert len(rockblock.requests) == 1
    assert list(rockblock.queues[IMEI]) == [b"[PARACHUTE=14:05]"]


def test_connection_reset_after_the_request_is_unknown_and_never_sent_twice(
    rockblock: SimulatedRockblock,
) -> None:
    rockblock.script(Scripted("reset"))
    result = client(rockblock.url).send(IMEI, b"[SOUNDER_ON]")
    assert result.status == "unknown"
    assert len(rockblock.requests) == 1


def test_refused_connections_are_retried_because_nothing_was_sent() -> None:
    port = free_port()
    started: list[SimulatedRockblock] = []

    def bring_gateway_up(_delay: float) -> None:
        if not started:
            started.append(SimulatedRockblock(username="ops", password=SECRET, port=port).start())

    try:
        result = client(f"http://127.0.0.1:{port}/rockblock/MT", sleep=bring_gateway_up).send(
            IMEI, b"[INTERVAL=3]"
        )
        assert (result.status, result.attempts) == ("queued", 2)
        assert len(started[0].requests) == 1
    finally:
        for gateway in started:
            gateway.stop()


def test_unreachable_gateway_is_not_sent_after_all_attempts(caplog: pytest.LogCaptureFixture) -> None:
    port = free_port()
    with caplog.at_level("DEBUG"):
        result = client(f"http://127.0.0.1:{port}/rockblock/MT", connect_attempts=3).send(
            IMEI, b"[INTERVAL=3]"
        )
    assert "connect attempt 3 failed, nothing sent" in caplog.text and SECRET not in caplog.text
    assert (result.status, result.attempts) == ("not_sent", 3)
    assert "nothing was sent" in result.detail and SECRET not in result.detail


def test_flush_is_sent_only_when_asked(rockblock: SimulatedRockblock) -> None:
    client(rockblock.url).send(IMEI, b"[INTERVAL=3]")
    client(rockblock.url).send(IMEI, b"[INTERVAL=4]", flush=True)
    assert "flush" not in rockblock.requests[0].form
    assert rockblock.requests[1].form["flush"] == "yes"
    assert list(rockblock.queues[IMEI]) == [b"[INTERVAL=4]"]


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("https://ops:pw@rockblock.rock7.com/rockblock/MT", "must not carry credentials"),
        ("https://rockblock.rock7.com/rockblock/MT?password=x", "must not carry credentials"),
        ("http://rockblock.rock7.com/rockblock/MT", "use https"),
        ("ftp://rockblock.rock7.com/", "not an http(s) URL"),
    ],
)
def test_endpoints_that_would_leak_credentials_are_refused(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        client(url)


class MemoryKeyring(KeyringBackend):
    """An OS keyring stand-in: the real backends need a desktop session this machine lacks."""

    priority = 1  # type: ignore[assignment]

    def __init__(self) -> None:
        super().__init__()
        self.secrets: dict[tuple[str, str], str] = {}

    def get_password(self, service: str, username: str) -> str | None:
        return self.secrets.get((service, username))

    def set_password(self, service: str, username: str, password: str) -> None:
        self.secrets[(service, username)] = password

    def delete_password(self, service: str, username: str) -> None:
        self.secrets.pop((service, username), None)


def test_password_comes_from_the_named_environment_variable_then_the_keyring() -> None:
    import keyring

    config = RockblockConfig(username="ops", password_env="DRS_TEST_RB_PW", keyring_service="drs-rockblock")
    assert resolve_password(config, {"DRS_TEST_RB_PW": "from-env"}) == "from-env"
    previous = keyring.get_keyring()
    memory = MemoryKeyring()
    memory.set_password("drs-rockblock", "ops", "from-keyring")
    keyring.set_keyring(memory)
    try:
        assert resolve_password(config, {}) == "from-keyring"
        memory.delete_password("drs-rockblock", "ops")
        with pytest.raises(ConfigError, match="DRS_TEST_RB_PW or the keyring service 'drs-rockblock'"):
            resolve_password(config, {})
    finally:
        keyring.set_keyring(previous)
