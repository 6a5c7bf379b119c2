"""The capsules on the chase team's map: Horus UDP ``PAYLOAD_SUMMARY`` packets for chasemapper.

A chase car runs chasemapper fed by Horus UDP (horus-gui on 55672, auto_rx on 55673). Each capsule
with a position (its newest Iridium fix in the store) is sent under its own name with the fields
horusdemodlib's ``send_payload_summary`` writes and chasemapper reads: ``callsign``, ``latitude``,
``longitude``, ``altitude`` (m), ``speed`` (km/h, -1 unknown), ``heading`` (-1 unknown), ``time``
(``HH:MM:SS`` UTC) and ``comment``. A capsule with a live prediction also has a landing marker,
``NAME_LAND``, that chasemapper shows but never flies.

chasemapper 1.6.0 (``horusmapper.py``, ``run_prediction``) predicts every callsign whose track holds
two points or more, and a track grows by every packet newer than its last point
(``handle_new_payload_position``). A landing re-sent at each new prediction became a "payload" with a
speed, flown 0 → 30 km every 15 s. So each marker is a track of one point: it is sent at one fixed
position and one fixed time (its repeats are dropped there as duplicates), and when the predicted
landing has moved more than ``MARKER_MOVE_M`` from it, the next marker takes the next callsign
(``NAME_LAND2``, ``NAME_LAND3``, …). The exact latest prediction is the KML overlay's. An OziMux
``WAYPOINT`` line would not do: chasemapper's OziListener parses it, but ``horusmapper.py`` never
gives it a ``waypoint_callback``, so it is not shown at all.

Everything is sent again every period: chasemapper keeps only what it hears, so a laptop started
late still gets every capsule within one period, and a repeated fix is dropped there as a duplicate.
The console keeps its latest predictions in the store (``ChaseStore``), so ``drs chase`` in another
terminal or on another machine sends the same landings, and as a KML at a fixed path per capsule for
chasemapper's ``[kml_overlays]``. The comment starts with ``OWN_COMMENT`` so our own balloon feed,
listening on the same port, does not take a capsule for the balloon.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING

from drs_link.config import Config, host_port
from drs_link.errors import LinkError
from drs_link.feeds.balloon_feed import OWN_COMMENT
from drs_link.feeds.chase_point import ChasePoint, KeptLanding
from drs_link.iridium import ReportStore
from drs_link.store import Store, iso_utc, parse_iso_utc
from predictor.tawhiri import FIXES_PER_CAPSULE, CapsuleFix, surface_distance_m

if TYPE_CHECKING:  # the predictor (numba) loads only where a prediction is kept
    from drs_link.iridium import Fix
    from predictor.prediction import Prediction

log = logging.getLogger(__name__)

CHASE_PERIOD_S = 10.0
LIVE_LANDING_S = 900.0
"""A kept landing older than this is not sent: the console predicts every minute, so it has stopped."""
LANDING_SUFFIX = "_LAND"
MARKER_MOVE_M = 2000.0
"""A landing this far from its marker gets a new marker: well inside the 1σ ellipse of a live
re-prediction, and few enough markers (a handful per descent) not to crowd the map."""

CHASE_DDL = """
CREATE TABLE IF NOT EXISTS chase_landing (
    capsule TEXT PRIMARY KEY,
    predicted_utc TEXT NOT NULL,
    landing_utc TEXT NOT NULL,
    lat REAL NOT NULL,
    lon REAL NOT NULL,
    alt_m REAL NOT NULL,
    kind TEXT NOT NULL,
    is_demo INTEGER NOT NULL
);
CREATE TABLE IF NOT EXISTS chase_marker (
    capsule TEXT PRIMARY KEY,
    number INTEGER NOT NULL,
    marked_utc TEXT NOT NULL,
    lat REAL NOT NULL,
    lon REAL NOT NULL,
    alt_m REAL NOT NULL
);
"""


@dataclass(frozen=True)
class LandingMarker:
    """Where chasemapper shows a capsule's landing: one fixed point and time per callsign."""

    capsule: str
    number: int
    marked_at: datetime
    lat: float
    lon: float
    alt_m: float

    @property
    def callsign(self) -> str:
        return self.capsule + LANDING_SUFFIX + ("" if self.number == 1 else str(self.number))


def chase_kml_path(data_dir: Path, capsule: str) -> Path:
    """Where a capsule's latest prediction is kept: one fixed path for chasemapper's ``overlay_N_path``."""
    return data_dir / "chase" / f"{capsule}.kml"


def write_chase_kml(prediction: Prediction, kml: Path) -> None:
    """The prediction's KML at its fixed path, whole: chasemapper may read the overlay at any moment."""
    from predictor.prediction import write_kml

    kml.parent.mkdir(parents=True, exist_ok=True)
    partial = kml.with_name(kml.name + ".partial")
    write_kml(prediction, partial)
    os.replace(partial, kml)


class ChaseStore:
    """The latest landing prediction of each capsule, shared by the console and ``drs chase``."""

    def __init__(self, store: Store) -> None:
        self.store = store
        store.ensure_schema(CHASE_DDL)

    def record(self, landing: KeptLanding) -> None:
        """Remember the landing, and move its marker to it (a new callsign) if it has gone too far."""
        marker = self.markers().get(landing.capsule)
        moved = (
            marker is None
            or surface_distance_m(marker.lat, marker.lon, landing.lat, landing.lon) > MARKER_MOVE_M
        )
        with self.store.transaction() as conn:
            conn.execute(
                "INSERT OR REPLACE INTO chase_landing VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (landing.capsule, iso_utc(landing.predicted_at), iso_utc(landing.landing_time), landing.lat,
                 landing.lon, landing.alt_m, landing.kind, int(landing.is_demo)),
            )  # fmt: skip
            if moved:
                number = 1 if marker is None else marker.number + 1
                conn.execute(
                    "INSERT OR REPLACE INTO chase_marker VALUES (?, ?, ?, ?, ?, ?)",
                    (landing.capsule, number, iso_utc(landing.predicted_at), landing.lat, landing.lon,
                     landing.alt_m),
                )  # fmt: skip

    def markers(self) -> dict[str, LandingMarker]:
        rows = self.store.query("SELECT * FROM chase_marker")
        return {
            row["capsule"]: LandingMarker(
                row["capsule"],
                row["number"],
                parse_iso_utc(row["marked_utc"]),
                row["lat"],
                row["lon"],
                row["alt_m"],
            )  # fmt: skip
            for row in rows
        }

    def landings(self) -> dict[str, KeptLanding]:
        rows = self.store.query("SELECT * FROM chase_landing")
        return {
            row["capsule"]: KeptLanding(
                row["capsule"],
                parse_iso_utc(row["predicted_utc"]),
                parse_iso_utc(row["landing_utc"]),
                row["lat"],
                row["lon"],
                row["alt_m"],
                row["kind"],
                bool(row["is_demo"]),
            )  # fmt: skip
            for row in rows
        }


def newest_fixes(reports: ReportStore, imei: str | None, count: int) -> list[Fix]:
    """The capsule's ``count`` newest position fixes, oldest first (a report without a fix is skipped)."""
    stored = reports.for_imei(imei) if imei else []
    fixes = [r.report.fix for r in stored if r.report is not None and r.report.fix is not None]
    return fixes[-count:]


def capsule_fixes(config: Config, store: Store) -> list[CapsuleFix]:
    """Every configured capsule's newest fixes, for the predictor server to know a capsule's request
    from any other payload's (``predictor.tawhiri.capsules``)."""
    reports = ReportStore(store)
    return [
        CapsuleFix(capsule.name, fix.time, fix.lat, fix.lon, float(fix.alt_m))
        for capsule in config.capsules
        for fix in newest_fixes(reports, capsule.imei, FIXES_PER_CAPSULE)
    ]


class StoredFixes:
    """The capsules' newest fixes read from the store at each call: ``drs serve predictor``'s fix source.

    It opens the store the configuration names (without OperatorOps: it only reads positions); SQLite
    gives each request thread its own connection."""

    def __init__(self, config: Config) -> None:
        self.config = config
        self.store = Store.open(config.store_path)

    def __call__(self) -> list[CapsuleFix]:
        return capsule_fixes(self.config, self.store)


def chase_points(config: Config, store: Store, now: datetime) -> list[ChasePoint]:
    """Each configured capsule's newest fix, and its landing if one was predicted in the last minutes."""
    reports = ReportStore(store)
    chase = ChaseStore(store)
    landings, markers = chase.landings(), chase.markers()
    points = []
    for capsule in config.capsules:
        newest = newest_fixes(reports, capsule.imei, 1)
        if newest:
            fix = newest[0]
            points.append(ChasePoint(
                capsule.name, fix.time, fix.lat, fix.lon, float(fix.alt_m), fix.speed_ms * 3.6,
                float(fix.course_deg), f"{OWN_COMMENT} capsule {capsule.name}, Iridium fix",
            ))  # fmt: skip
        land, marker = landings.get(capsule.name), markers.get(capsule.name)
        if (
            land is not None
            and marker is not None
            and now - land.predicted_at <= timedelta(seconds=LIVE_LANDING_S)
        ):
            demo = " DEMO weather, not a forecast" if land.is_demo else ""
            points.append(ChasePoint(
                marker.callsign, marker.marked_at, marker.lat, marker.lon, marker.alt_m, None, None,
                f"{OWN_COMMENT} predicted landing {land.landing_time:%H:%M}Z ({land.kind}){demo}",
            ))  # fmt: skip
    return points


class ChaseSender:
    """One UDP socket to the chase LAN; a broadcast address is allowed (chasemapper listens on any)."""

    address: tuple[str, int] | tuple[str, int, int, int] | tuple[int, bytes]
    """Where the datagrams go, as ``getaddrinfo`` gives it for IPv4 or IPv6."""

    def __init__(self, target: str, key: str = "--udp") -> None:
        self.host, self.port = host_port(target, key)
        # An IPv6 address in brackets, as a person writes it back (::1:55683 reads as one address).
        self.target = f"[{self.host}]:{self.port}" if ":" in self.host else f"{self.host}:{self.port}"
        try:
            family, kind, proto, _, self.address = socket.getaddrinfo(
                self.host, self.port, type=socket.SOCK_DGRAM
            )[0]
        except OSError as exc:
            raise LinkError(f"cannot send to udp {self.target}: {exc.strerror or exc}") from None
        self._sock = socket.socket(family, kind, proto)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)

    def send(self, points: Sequence[ChasePoint]) -> None:
        for point in points:
            data = json.dumps(point.packet()).encode("ascii")
            try:
                self._sock.sendto(data, self.address)
            except OSError as exc:
                raise LinkError(f"cannot send to udp {self.target}: {exc.strerror or exc}") from None

    def close(self) -> None:
        self._sock.close()


class ChaseFeed:
    """Sends ``points()`` every ``period_s`` on its own thread until stopped; a failed round is logged and retried."""

    def __init__(
        self, sender: ChaseSender, points: Callable[[], list[ChasePoint]], period_s: float = CHASE_PERIOD_S
    ) -> None:
        self.sender = sender
        self._points = points
        self.period_s = period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"chase feed {sender.target}", daemon=True)

    def start(self) -> ChaseFeed:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10.0)
        self.sender.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self.sender.send(self._points())
            except Exception:  # the console's other work goes on: the team sees it in the log
                log.exception("chase feed to %s: a round failed", self.sender.target)
            self._stop.wait(self.period_s)
