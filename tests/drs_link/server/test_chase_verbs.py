"""The chase verbs of the operations server: a console's kept landing reaches every `drs chase` through
the server's one store, and a landing that is no place on Earth, or no configured capsule's, is refused
and changes nothing. A real private server in this process, over its Unix socket."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest

from drs_link.config import load_config
from drs_link.errors import ConfigError, LinkError, RefusedError
from drs_link.feeds import KeptLanding
from drs_link.server.client import Client


@pytest.fixture
def client(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Client:
    monkeypatch.setenv("DRS_PRIVATE_SERVER", "thread")
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "EL"\n[data]\ndir = "{tmp_path / "data"}"\n'
        '[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\n'
    )
    return Client.for_config(load_config(config))


def landing(**changes: object) -> KeptLanding:
    now = datetime.now(UTC)
    fields: dict[str, object] = dict(capsule="DRS1", predicted_at=now, landing_time=now, lat=51.45,
                                     lon=-0.30, alt_m=35.0, kind="live re-prediction", is_demo=False)  # fmt: skip
    return KeptLanding(**{**fields, **changes})  # type: ignore[arg-type]


def test_a_kept_landing_is_sent_by_drs_chase_as_its_marker(client: Client) -> None:
    assert client.chase.points() == []
    client.chase.keep(landing())
    [marker] = client.chase.points()
    assert marker.callsign == "DRS1_LAND" and (marker.lat, marker.lon) == (51.45, -0.30)
    assert "predicted landing" in marker.comment and "(live re-prediction)" in marker.comment


@pytest.mark.parametrize(
    ("changes", "refusal", "error"),
    [
        ({"lat": 91.0}, "landing latitude 91.0 is not on Earth", RefusedError),
        ({"lon": 180.5}, "landing longitude 180.5 is not on Earth", RefusedError),
        ({"alt_m": float("nan")}, "malformed KeepLandingRequest: Expected `float`, got `null`", LinkError),
        ({"kind": "\x1b[2Kforged"}, "a kept landing is one of live re-prediction, release now", RefusedError),
        ({"capsule": "DRS9"}, "no capsule named 'DRS9'", ConfigError),
    ],
)
def test_a_landing_that_is_no_place_or_no_capsules_is_refused_and_changes_nothing(
    client: Client, changes: dict[str, object], refusal: str, error: type[Exception]
) -> None:
    with pytest.raises(error, match=refusal.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")):
        client.chase.keep(landing(**changes))
    assert client.chase.points() == []
