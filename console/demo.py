"""The demo world: three simulated capsules on a drifting balloon, a simulated RockBLOCK, weather and terrain.

Everything the console talks to is the real protocol on loopback: the capsules are B's SSH
simulators (host keys pinned, GPIO interlock, firmware timing), the gateway is C's simulated
RockBLOCK, and the reports of a released capsule are POSTed as webhooks to the console's own MO
receiver. A released capsule descends along the predictor's own physics (demo weather, demo
terrain) with a wind error and GNSS noise, so the measured track and the prediction differ as
they do on a real flight. Time runs ``speed`` times faster than the wall clock, everywhere.
"""

from __future__ import annotations

import json
import math
import random
import secrets
import socket
import threading
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import xarray as xr

from drs_link.config import Config, MoConfig, parse_config
from drs_link.feeds import format_ozimux
from drs_link.iridium import GnssFix, MoHttpServer, MoReceiver, ReportStore
from drs_link.sim import (
    CapsuleSimulator,
    GnssSky,
    SimulatedCapsule,
    SimulatedRockblock,
    generate_test_keys,
    post_mo,
    write_ed25519,
)
from drs_link.store import Store
from predictor import FlightSetup, Release, Terrain, WeatherCube, load_weather, predict
from predictor.environment import demo_weather_files

SITE = (67.8887, 21.0856)
"""Esrange, where the simulated capsules' GNSS starts."""
FLOAT_ALT_M = 31500.0
CAPSULES = (
    ("DRS1", "300434060000010", 17001),
    ("DRS2", "300434060000020", 17002),
    ("DRS3", "300434060000030", 17003),
)
SERVO_A_AFTER_GO_S = 32.0
WIND_ERROR_MS = 1.2
GNSS_NOISE_M = 6.0
REPORT_FOR_S = 6 * 3600.0
PAYLOAD_FILES = 3
PAYLOAD_FILE_BYTES = 256 * 1024
LOOP_S = 0.2
BALLOON_REPORT_S = 5
"""How often (simulated seconds) the demo's ground station sends the balloon's position."""


def write_demo_terrain(path: Path) -> Path:
    """A smooth DEM around the site: fells rising to ~1.5 km in the west, lower land to the east."""
    lats = np.arange(60.0, 75.0001, 0.1)
    lons = np.arange(8.0, 36.0001, 0.1)
    lat2, lon2 = np.meshgrid(lats, lons, indexing="ij")
    fells = 1300.0 * np.exp(-(((lon2 - 18.5) / 2.0) ** 2) - ((lat2 - 68.0) / 2.5) ** 2)
    rolling = 120.0 * np.sin(lon2 * 2.1) * np.cos(lat2 * 1.7) + 350.0
    heights = np.maximum(fells + rolling, 0.0)
    ds = xr.Dataset(
        {"elevation": (("lat", "lon"), heights)},
        coords={
            "lat": ("lat", lats, {"units": "degrees_north"}),
            "lon": ("lon", lons, {"units": "degrees_east"}),
        },
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    ds.to_netcdf(path, engine="scipy")
    return path


def write_exclusion_zones(path: Path) -> Path:
    def box(name: str, lat0: float, lat1: float, lon0: float, lon1: float) -> dict[str, object]:
        ring = [[lon0, lat0], [lon1, lat0], [lon1, lat1], [lon0, lat1], [lon0, lat0]]
        return {
            "type": "Feature",
            "properties": {"name": name},
            "geometry": {"type": "Polygon", "coordinates": [ring]},
        }

    document = {
        "type": "FeatureCollection",
        "features": [
            box("Kiruna town", 67.82, 67.88, 20.12, 20.35),
            box("Vidsel test range", 67.40, 67.75, 22.90, 23.60),
        ],
    }
    path.write_text(json.dumps(document, indent=1), encoding="utf-8")
    return path


@dataclass
class Descent:
    """One released capsule's measured descent: the predicted path, a constant wind error, GNSS noise."""

    capsule: SimulatedCapsule
    start: datetime
    t_s: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray
    error_ms: tuple[float, float]
    next_report: datetime
    rng: random.Random = field(default_factory=random.Random)

    def position(self, at: datetime) -> tuple[float, float, float, float]:
        """(lat, lon, alt, speed) at a moment: on the path, blown off it by the wind error, plus noise."""
        elapsed = max(0.0, (at - self.start).total_seconds())
        flying = min(elapsed, float(self.t_s[-1]))
        lat = float(np.interp(flying, self.t_s, self.lat))
        lon = float(np.interp(flying, self.t_s, self.lon))
        alt = float(np.interp(flying, self.t_s, self.alt_m))
        north = self.error_ms[1] * flying + self.rng.gauss(0.0, GNSS_NOISE_M)
        east = self.error_ms[0] * flying + self.rng.gauss(0.0, GNSS_NOISE_M)
        lat += north / 111_320.0
        lon += east / (111_320.0 * math.cos(math.radians(lat)))
        speed = (
            0.0 if elapsed >= self.t_s[-1] else abs(float(np.interp(flying + 1, self.t_s, self.alt_m)) - alt)
        )
        return lat, lon, alt, speed


class DemoWorld:
    """Start with ``start()`` (returns the console's configuration), stop with ``stop()``."""

    def __init__(self, root: Path, speed: float = 4.0, seed: int = 1) -> None:
        if not 0.5 <= speed <= 200:
            raise ValueError("demo speed must be between 0.5 and 200")
        self.root = root
        self.speed = speed
        self.rng = random.Random(seed)
        self.sims: list[CapsuleSimulator] = []
        self.iridium: dict[str, SimulatedCapsule] = {}
        self.descents: dict[str, Descent] = {}
        self.balloon = [SITE[0], SITE[1], FLOAT_ALT_M]
        self.balloon_velocity = [9.0, 1.5]
        self.gateway: SimulatedRockblock | None = None
        self.receiver: MoHttpServer | None = None
        self.store: Store | None = None
        self.weather_files: list[Path] = []
        self.terrain_file = root / "terrain" / "demo-dem.nc"
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_step: datetime | None = None
        self._cube: WeatherCube | None = None
        self._terrain: Terrain | None = None
        self.config_table: dict[str, object] = {}
        self._ground_station = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.ground_station_port = _free_udp_port()
        """Where the demo's ground station sends the balloon's position (OziMux), as a real one would."""

    def clock(self) -> datetime:
        return self.sims[0].clock.now()

    def start(self) -> Config:
        self.root.mkdir(parents=True, exist_ok=True)
        key_path = self.root / "keys" / "id_ed25519"
        client_key = write_ed25519(key_path)
        known_hosts = self.root / "known_hosts"
        capsules = []
        for index, (name, imei, serial) in enumerate(CAPSULES):
            sky = GnssSky(latitude=SITE[0], longitude=SITE[1], altitude_m=FLOAT_ALT_M, hdop=0.9 + 0.4 * index)
            sim = CapsuleSimulator(name, [client_key], clock_scale=self.speed, sky=sky)
            sim.faults.raid_degraded = name == "DRS3"
            sim.start()
            self.sims.append(sim)
            source = self.root / "payload-data" / name
            source.mkdir(parents=True, exist_ok=True)
            for number in range(PAYLOAD_FILES):
                (source / f"frames_{number:03d}.fits").write_bytes(self.rng.randbytes(PAYLOAD_FILE_BYTES))
            capsules.append({
                "name": name, "host": "127.0.0.1", "port": sim.port, "identity_file": str(key_path),
                "known_hosts": str(known_hosts), "python": "python3", "imei": imei, "rockblock_serial": serial,
                "sync_source": str(source), "connect_timeout_s": 5.0, "command_timeout_s": 30.0,
            })  # fmt: skip
            self.iridium[imei] = SimulatedCapsule(imei, serial)
        known_hosts.write_text("".join(sim.known_hosts_line() for sim in self.sims))
        self.gateway = SimulatedRockblock("drs-demo", secrets.token_urlsafe(12), tuple(self.iridium)).start()
        data_dir = self.root / "data"
        self.store = Store.open(data_dir / "drs.sqlite")
        self.store.run_clock(self.clock(), self.speed)  # every process on this store reads the demo's time
        # The demo gateway signs every delivery as Ground Control does, with a key of its own.
        self.jwt_private_key, public = generate_test_keys()
        self.jwt_public_key_file = self.root / "rockblock-jwt-public.pem"
        self.jwt_public_key_file.write_text(public)
        mo_config = MoConfig(listen_port=0, jwt_public_key_file=self.jwt_public_key_file)
        self.receiver = MoHttpServer(MoReceiver(ReportStore(self.store), mo_config, clock=self.clock)).start()
        write_demo_terrain(self.terrain_file)
        zones = write_exclusion_zones(self.root / "exclusion-zones.geojson")
        self.weather_files = demo_weather_files(SITE[0], SITE[1], self.clock(), hours=18)
        self.config_table = {
            "operator": {"name": "demo-operator"},
            "data": {"dir": str(data_dir)},
            "rockblock": {"mt_url": self.gateway.url, "username": "drs-demo"},
            "balloon_feed": {"kind": "udp", "host": "127.0.0.1", "port": self.ground_station_port},
            "console": {
                "arm_window_s": max(120.0, 10.0 * self.speed), "exclusion_zones_file": str(zones),
                "team_position": f"{SITE[0] - 0.25:.4f},{SITE[1] + 0.9:.4f}",
                "prediction_period_s": 60.0,
            },
            "capsule": capsules,
        }  # fmt: skip
        """The configuration as TOML tables, every path absolute (``drs demo --live`` writes it to a file)."""
        config = parse_config(self.config_table)
        self._thread = threading.Thread(target=self._run, name="demo-world", daemon=True)
        self._thread.start()
        return config

    @property
    def environ(self) -> dict[str, str]:
        """The gateway password as the console reads it (an environment variable, never a file)."""
        assert self.gateway is not None
        return {"DRS_ROCKBLOCK_PASSWORD": self.gateway.password}

    def terrain(self) -> Terrain:
        return Terrain.from_netcdf(self.terrain_file)

    def send_balloon_position(self, now: datetime) -> None:
        lat, lon, alt = self.balloon
        line = format_ozimux(now, lat, lon, alt)
        self._ground_station.sendto(line.encode("ascii"), ("127.0.0.1", self.ground_station_port))

    # The world's own time step ----------------------------------------------------------------

    def _run(self) -> None:
        while not self._stop.wait(LOOP_S):
            try:
                self.step(self.clock())
            except Exception as exc:  # the demo must keep running; the console shows what it sees
                print(f"demo world: {type(exc).__name__}: {exc}", flush=True)

    def step(self, now: datetime) -> None:
        dt = 0.0 if self._last_step is None else (now - self._last_step).total_seconds()
        self._last_step = now
        for axis in (0, 1):
            self.balloon_velocity[axis] += self.rng.gauss(0.0, 0.02 * math.sqrt(max(dt, 0.0)))
        self.balloon[0] += self.balloon_velocity[1] * dt / 111_320.0
        self.balloon[1] += (
            self.balloon_velocity[0] * dt / (111_320.0 * math.cos(math.radians(self.balloon[0])))
        )
        previous = now.timestamp() - dt
        if dt == 0.0 or now.timestamp() // BALLOON_REPORT_S != previous // BALLOON_REPORT_S:
            self.send_balloon_position(now)
        for sim, (name, imei, _) in zip(self.sims, CAPSULES, strict=True):
            go_at = sim.firmware.go_at
            if go_at is None:
                sim.firmware.sky.latitude, sim.firmware.sky.longitude = self.balloon[0], self.balloon[1]
                continue
            if name not in self.descents:
                release = go_at + timedelta(seconds=SERVO_A_AFTER_GO_S)
                if now < release:
                    continue
                self.descents[name] = self._descent(imei, release)
            self._report(self.descents[name], now)

    def _descent(self, imei: str, release: datetime) -> Descent:
        if self._cube is None:
            self._cube = load_weather(self.weather_files)
            self._terrain = self.terrain()
        lat, lon, alt = self.balloon
        setup = FlightSetup(terrain=self._terrain or Terrain.sea_level())
        result = predict(self._cube, Release(release, lat, lon, alt), setup)
        track = result.track
        error = (self.rng.gauss(0.0, WIND_ERROR_MS), self.rng.gauss(0.0, WIND_ERROR_MS))
        return Descent(
            self.iridium[imei], release, np.asarray(track.t_s), np.asarray(track.lat), np.asarray(track.lon),
            np.asarray(track.alt_m), error, release + timedelta(seconds=20), random.Random(self.rng.random()),
        )  # fmt: skip

    def _report(self, descent: Descent, now: datetime) -> None:
        assert self.gateway is not None and self.receiver is not None
        while (
            descent.next_report <= now
            and (descent.next_report - descent.start).total_seconds() < REPORT_FOR_S
        ):
            at = descent.next_report
            lat, lon, alt, speed = descent.position(at)
            fix = GnssFix(at.replace(microsecond=0), lat, lon, alt, speed, 90.0, 0.9, 9)
            capsule = descent.capsule
            capsule.vbat = max(6.0, capsule.vbat - 0.004)
            delivery = capsule.session(
                self.gateway, fix, at + timedelta(seconds=15), (lat + 0.01, lon - 0.02, 4.0)
            )
            post_mo(self.receiver.url, delivery, jwt_private_key=self.jwt_private_key)
            descent.next_report = capsule.next_cycle(at)

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        if self.receiver is not None:
            self.receiver.stop()
        if self.gateway is not None:
            self.gateway.stop()
        for sim in self.sims:
            sim.stop()
        if self.store is not None:
            self.store.close()
        self._ground_station.close()


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])
