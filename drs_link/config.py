"""The operator's TOML configuration, read into typed settings.

A wrong key on launch day must fail loudly and name itself, so every table is checked against
the fields of its dataclass: unknown keys, wrong types and bad values raise ``ConfigError``
with the dotted key (``capsule[1].port``) in the message.

Where the file is: ``--config FILE``, else ``$DRS_CONFIG``, else ``drs.toml`` in the platform's
config directory (platformdirs: ``$XDG_CONFIG_HOME/drs``, by default ``~/.config/drs``, on Linux).
The store and the console's known_hosts default to the data and config directories the same way.
Before XDG these were fixed at ``~/.config/drs`` and ``~/.local/share/drs``; a file found only
there is still used, with a warning that says where it belongs now, so no launch-day setup breaks.
"""

from __future__ import annotations

import dataclasses
import ipaddress
import logging
import math
import os
import re
import stat
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import platformdirs

from drs_link.errors import ConfigError
from drs_link.link.backends import backend_names

log = logging.getLogger(__name__)

CONFIG_ENV = "DRS_CONFIG"
CONFIG_NAME = "drs.toml"
LEGACY_CONFIG_DIR = Path("~/.config/drs")
LEGACY_DATA_DIR = Path("~/.local/share/drs")
DEFAULT_BACKEND = "stock"
"""The flown scripts, what capsules carry; named first where the backends are listed."""


_warned_legacy: set[Path] = set()
"""Old places already warned about: every capsule's known_hosts default asks again, once is enough."""


def _current_or_legacy(directory: Path, legacy: Path, name: str) -> Path:
    """``directory/name``, unless only the pre-XDG ``legacy/name`` exists: then that, with a warning."""
    current, old = directory / name, legacy.expanduser() / name
    if current != old and not _exists(current) and _exists(old):
        if old not in _warned_legacy:
            _warned_legacy.add(old)
            log.warning(
                "using %s from its old place; the default is now %s (move it, or keep it there)", old, current
            )
        return old
    return current


def _exists(path: Path) -> bool:
    """Whether ``path`` is there; one behind a directory this account cannot enter counts as not there.

    ``Path.exists`` raises on EACCES: an operator whose ``$XDG_DATA_HOME`` was another account's (a
    ``sudo -E``, the test suite's own directories) could not run even a command that never opens the
    store. Whatever does open the file later says why it cannot."""
    try:
        return path.exists()
    except OSError:
        return False


def default_config_path() -> Path:
    return _current_or_legacy(platformdirs.user_config_path("drs"), LEGACY_CONFIG_DIR, CONFIG_NAME)


def default_data_dir() -> Path:
    """The store's directory: the XDG data directory, or the old one when only it holds a store."""
    return _current_or_legacy(platformdirs.user_data_path("drs"), LEGACY_DATA_DIR, "drs.sqlite").parent


def default_known_hosts() -> Path:
    return _current_or_legacy(platformdirs.user_config_path("drs"), LEGACY_CONFIG_DIR, "known_hosts")


def config_help() -> str:
    """``--config``'s help, naming the real default on this machine."""
    return f"configuration TOML (default: ${CONFIG_ENV}, else {platformdirs.user_config_path('drs') / CONFIG_NAME})"


CAPSULE_NAME_RE = re.compile(r"\A[A-Za-z0-9_-]{1,32}\Z")
IMEI_RE = re.compile(r"\A[0-9]{15}\Z")
r"""ASCII digits, and ``\Z``: ``\d`` took full-width digits and ``$`` a trailing newline, and a capsule so
configured matched none of its reports."""
MO_PATH_RE = re.compile(r"\A/[A-Za-z0-9._~/-]*\Z")
"""What a gateway's URL path can carry as written: a ``?`` starts the query and non-ASCII is sent
percent-encoded, so either made every delivery a 404."""
MAX_SECRET_FILE_BYTES = 1_048_576
"""A key, identity or known_hosts file is a few kB; ``/dev/zero`` as one was read until MemoryError."""


@dataclass(frozen=True)
class OperatorConfig:
    name: str = ""


@dataclass(frozen=True)
class OperatorAccount:
    """One ``[[operator]]`` of an operations server's own configuration: the OS account the kernel names
    for a connection, and the operator name it acts and is audited under (``drs_link.server``)."""

    account: str
    name: str


@dataclass(frozen=True)
class ServerConfig:
    """Where this account's ``drs`` finds the team's operations server (``drs setup server``): its Unix
    socket. Empty: a private server of this account, started on demand."""

    socket: str = ""


@dataclass(frozen=True)
class DataConfig:
    dir: Path = field(default_factory=default_data_dir)


@dataclass(frozen=True)
class RockblockConfig:
    mt_url: str = "https://rockblock.rock7.com/rockblock/MT"
    username: str = ""
    password_env: str = "DRS_ROCKBLOCK_PASSWORD"
    keyring_service: str = ""
    timeout_s: float = 20.0


@dataclass(frozen=True)
class MoConfig:
    """The webhook receiver for Mobile Originated reports (`drs mo serve`)."""

    listen_host: str = "127.0.0.1"
    listen_port: int = 8088
    path: str = "/rockblock/mo"
    jwt_public_key_file: Path | None = None
    require_jwt: bool = True
    """Unsigned deliveries are refused unless the operator opts out (a forged landing fix misleads recovery)."""
    max_body_bytes: int = 16384
    trusted_proxy: str = ""
    """The reverse proxy's address as the receiver sees it (``127.0.0.1``): only its X-Forwarded-For names the
    client in the audit; "" trusts none (a header anyone can write would let them forge the sender)."""


@dataclass(frozen=True)
class ConsoleConfig:
    """The operator console (`drs console`): release rules and what it shows."""

    arm_window_s: float = 60.0
    require_second_operator: bool = False
    crew: tuple[str, ...] = ()
    """Who may be typed as a second operator when ``require_second_operator`` is off."""
    exclusion_zones_file: Path | None = None
    team_position: str = ""
    prediction_period_s: float = 60.0
    low_bandwidth: bool = False
    """Over a thin SSH link: no animation, no zebra stripes, ages in 10-s steps (countdowns stay exact)."""


@dataclass(frozen=True)
class BalloonFeedConfig:
    """Where the balloon's position comes from before any capsule's GNSS is on: a ground station on the LAN.

    ``kind`` "" means no feed. ``host``/``port`` are the address a UDP feed listens on or a TCP feed
    connects to (8942: auto_rx's OziMux lines; horus-gui's are on 55683, Horus UDP on 55672/55673);
    ``path`` is the log a file feed follows.
    """

    kind: str = ""
    host: str = "127.0.0.1"
    port: int = 8942
    path: Path | None = None


@dataclass(frozen=True)
class ChaseConfig:
    """Where the capsules' positions go to the chase team's chasemapper, as Horus UDP (``drs chase`` and the console).

    ``udp`` is ``HOST:PORT``, "" for none: chasemapper's horus_udp profiles listen on 55672 (horus-gui's
    port) or 55673 (auto_rx's); a broadcast address such as 255.255.255.255 reaches every car on the LAN.
    """

    udp: str = ""


@dataclass(frozen=True)
class CapsuleConfig:
    name: str
    host: str
    port: int = 22
    user: str = "pi"
    identity_file: Path | None = None
    known_hosts: Path = field(default_factory=default_known_hosts)
    jump_host: str | None = None
    tools_dir: str = "/home/pi/DRS_Python_Tools"
    python: str = "python"
    agent_python: str = "python3"
    storage_mount: str = "/mnt/raid1"
    raid_device: str = "/dev/md0"
    serial_device: str = "/dev/ttyS0"
    backend: str = DEFAULT_BACKEND
    rockblock_serial: int | None = None
    imei: str | None = None
    model: Path | None = None
    """A calibrated model (``drs calibrate --save-model``) this capsule's predictions fly; default: the
    drs payload profile. (Replaces the ``payload`` key, which was read and never used.)"""
    connect_timeout_s: float = 10.0
    command_timeout_s: float = 60.0
    microcontroller_wait_s: float = 25.0
    authority_lease_s: float = 1800.0
    sync_source: Path | None = None


@dataclass(frozen=True)
class Config:
    operator: OperatorConfig = field(default_factory=OperatorConfig)
    data: DataConfig = field(default_factory=DataConfig)
    rockblock: RockblockConfig = field(default_factory=RockblockConfig)
    mo: MoConfig = field(default_factory=MoConfig)
    console: ConsoleConfig = field(default_factory=ConsoleConfig)
    balloon_feed: BalloonFeedConfig = field(default_factory=BalloonFeedConfig)
    chase: ChaseConfig = field(default_factory=ChaseConfig)
    capsules: tuple[CapsuleConfig, ...] = ()
    server: ServerConfig = field(default_factory=ServerConfig)
    operators: tuple[OperatorAccount, ...] = ()
    """A server's ``[[operator]]`` list (its own configuration only; a client's says ``[operator] name``)."""
    source: Path | None = None

    def capsule(self, name: str) -> CapsuleConfig:
        for capsule in self.capsules:
            if capsule.name == name:
                return capsule
        known = ", ".join(c.name for c in self.capsules) or "none configured"
        raise ConfigError(f"no capsule named {name!r} in {self.where()} (known: {known})")

    def where(self) -> str:
        """Which file these settings came from, or the path looked for when there was none: an error that
        says "none configured" must say where it looked, or the operator edits the wrong file."""
        if self.source is not None:
            return str(self.source)
        return (f"the defaults: no configuration file at {default_config_path()} "
                f"(create it, or give --config FILE or ${CONFIG_ENV})")  # fmt: skip

    @property
    def store_path(self) -> Path:
        return self.data.dir / "drs.sqlite"


def _expand(path: Path) -> Path:
    return Path(os.path.expandvars(str(path))).expanduser()


def _coerce(key: str, annotation: Any, value: Any) -> Any:
    """Check one TOML value against a field's type; paths are expanded, ints may become floats."""
    origin = typing.get_origin(annotation)
    if origin in (typing.Union, types.UnionType):
        options = [a for a in typing.get_args(annotation) if a is not type(None)]
        return _coerce(key, options[0], value)
    if annotation is Path:
        if not isinstance(value, str) or not value:
            raise ConfigError(f"{key}: expected a path (a non-empty string), got {value!r}")
        try:
            return _expand(Path(value))
        except RuntimeError:  # "~name" for a user this machine does not have
            raise ConfigError(
                f"{key}: {value!r} names the home of a user this machine does not have"
            ) from None
    if annotation is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{key}: expected true or false, got {value!r}")
        return value
    if annotation is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{key}: expected a whole number, got {value!r}")
        return value
    if annotation is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(f"{key}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(f"{key}: expected a finite number, got {value!r}")
        return float(value)
    if annotation is str:
        if not isinstance(value, str):
            raise ConfigError(f"{key}: expected a string, got {value!r}")
        return value
    if annotation == tuple[str, ...]:
        if not isinstance(value, list) or not all(isinstance(v, str) and v.strip() for v in value):
            raise ConfigError(f"{key}: expected a list of names, got {value!r}")
        return tuple(v.strip() for v in value)
    raise TypeError(f"unsupported config field type {annotation!r}")


def _build(cls: type, table: Any, prefix: str) -> Any:
    if not isinstance(table, dict):
        raise ConfigError(f"{prefix}: expected a table, got {table!r}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(table) - set(fields))
    if unknown:
        allowed = ", ".join(sorted(fields))
        raise ConfigError(f"{prefix}.{unknown[0]}: unknown key (allowed in [{prefix}]: {allowed})")
    kwargs = {}
    for name, f in fields.items():
        if name in table:
            kwargs[name] = _coerce(f"{prefix}.{name}", hints[name], table[name])
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ConfigError(f"{prefix}.{name}: required key is missing")
    return cls(**kwargs)


def _check_capsule(capsule: CapsuleConfig, key: str) -> None:
    if not CAPSULE_NAME_RE.match(capsule.name):
        raise ConfigError(f"{key}.name: {capsule.name!r} must be 1-32 letters, digits, '-' or '_'")
    _check_host(f"{key}.host", capsule.host)
    if not capsule.user or not capsule.user.isprintable() or any(c.isspace() for c in capsule.user):
        raise ConfigError(f"{key}.user: {capsule.user!r} must be a login name without spaces")
    if capsule.jump_host is not None:
        _check_jump_host(f"{key}.jump_host", capsule.jump_host)
    for name in ("identity_file", "known_hosts"):
        if (path := getattr(capsule, name)) is not None:
            _check_small_file(f"{key}.{name}", path)
    for name in ("tools_dir", "storage_mount", "raid_device", "serial_device"):
        if not getattr(capsule, name).startswith("/"):
            raise ConfigError(f"{key}.{name}: {getattr(capsule, name)!r} must be an absolute path on the Pi")
    for name in ("python", "agent_python"):
        if not getattr(capsule, name).strip():
            raise ConfigError(f"{key}.{name}: must name a Python interpreter on the Pi")
    if not 1 <= capsule.port <= 65535:
        raise ConfigError(f"{key}.port: {capsule.port} is not a TCP port (1-65535)")
    if capsule.backend not in backend_names():
        names = ", ".join(
            repr(name) for name in sorted(backend_names(), key=lambda name: name != DEFAULT_BACKEND)
        )
        raise ConfigError(f"{key}.backend: {capsule.backend!r} is not one of {names}")
    if capsule.imei is not None and not IMEI_RE.match(capsule.imei):
        raise ConfigError(f"{key}.imei: {capsule.imei!r} must be the modem's 15-digit IMEI")
    if capsule.rockblock_serial is not None and not 0 < capsule.rockblock_serial <= 9_999_999:
        raise ConfigError(f"{key}.rockblock_serial: {capsule.rockblock_serial} must be 1-9999999")
    for name in ("connect_timeout_s", "command_timeout_s", "microcontroller_wait_s", "authority_lease_s"):
        if getattr(capsule, name) <= 0:
            raise ConfigError(f"{key}.{name}: must be positive")
    _check_range(f"{key}.authority_lease_s", capsule.authority_lease_s, 1.0, MAX_LEASE_S,
                 "the Pi's shell arithmetic holds the lease's end in seconds")  # fmt: skip
    for name in ("connect_timeout_s", "command_timeout_s", "microcontroller_wait_s"):
        _check_range(f"{key}.{name}", getattr(capsule, name), 0.001, 3600.0, "a link that slow is down")


MAX_LEASE_S = 86_400.0
"""A day: a lease of 1e19 s overflowed the Pi's 64-bit shell arithmetic and let a second console take over."""
VARIABLE_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]{0,127}$")
PASSWORD_ENV_RE = re.compile(r"^[A-Z_][A-Z0-9_]{0,127}$")
"""Capitals only: ``password_env = "hunter2xyz"`` (the password itself) once passed and was printed by the
error that the variable is not set; a name in capitals is a name, a password rarely is."""


def _check_range(key: str, value: float, low: float, high: float, why: str) -> None:
    if not low <= value <= high:
        raise ConfigError(f"{key}: {value:g} is outside {low:.12g}–{high:.12g} ({why})")


def _check_sections(sections: dict[str, Any]) -> None:
    """Values that pass their type but reach arithmetic, a socket, a URL path or a shell."""
    operator: OperatorConfig | None = sections.get("operator")
    if operator is not None and (len(operator.name) > 64 or not operator.name.isprintable()):
        raise ConfigError(
            "operator.name: at most 64 printable characters (it is written to every audit record)"
        )
    data: DataConfig | None = sections.get("data")
    if data is not None and not data.dir.is_absolute():
        raise ConfigError(
            f"data.dir: {str(data.dir)!r} is relative, so the store would depend on the working directory; "
            "give an absolute path or one starting with ~"
        )
    rockblock: RockblockConfig | None = sections.get("rockblock")
    if rockblock is not None:
        _check_range(
            "rockblock.timeout_s", rockblock.timeout_s, 0.5, 600.0, "the gateway answers within seconds"
        )
        if rockblock.password_env and not PASSWORD_ENV_RE.match(rockblock.password_env):
            raise ConfigError(
                "rockblock.password_env: must be the NAME of an environment variable in capitals "
                "(A-Z, 0-9, _), such as DRS_ROCKBLOCK_PASSWORD; the value is not shown here in case it is "
                "the password itself"
            )
    mo: MoConfig | None = sections.get("mo")
    if mo is not None:
        _check_range("mo.listen_port", mo.listen_port, 0, 65535, "a TCP port; 0 picks a free one")
        _check_range("mo.max_body_bytes", mo.max_body_bytes, 256, 1_048_576,
                     "a gateway delivery is under 1 kB; below 256 every post would be refused")  # fmt: skip
        if mo.trusted_proxy:
            try:
                ipaddress.ip_address(mo.trusted_proxy)
            except ValueError:
                raise ConfigError(
                    f"mo.trusted_proxy: {mo.trusted_proxy!r} must be the proxy's IP address as the receiver "
                    "sees it (e.g. 127.0.0.1), not a name"
                ) from None
        if not MO_PATH_RE.match(mo.path):
            raise ConfigError(
                f"mo.path: {mo.path!r} must start with / and hold only ASCII letters, digits and . _ ~ / - "
                "(every post would get 404)"
            )
        if mo.jwt_public_key_file is not None:
            _check_small_file("mo.jwt_public_key_file", mo.jwt_public_key_file)
    console: ConsoleConfig | None = sections.get("console")
    if console is not None:
        _check_team_position(console.team_position)
        _check_range("console.arm_window_s", console.arm_window_s, 5.0, 3600.0, "seconds to FIRE after ARM")
        _check_range("console.prediction_period_s", console.prediction_period_s, 1.0, 3600.0, "seconds")
    chase: ChaseConfig | None = sections.get("chase")
    if chase is not None and chase.udp:
        host_port(chase.udp, "chase.udp")


def _check_team_position(text: str) -> None:
    """``LAT,LON`` in decimal degrees, finite and on the globe (``nan,nan`` once passed to the console)."""
    if not text.strip():
        return
    parts = text.replace(" ", "").split(",")
    try:
        lat, lon = (float(part) for part in parts)
    except ValueError:
        raise ConfigError(
            f"console.team_position: {text!r} must be LAT,LON in decimal degrees, e.g. 46.52,6.63"
        ) from None
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):  # False for nan
        raise ConfigError(
            f"console.team_position: {text!r} must be LAT,LON with -90<=LAT<=90 and -180<=LON<=180"
        )


def _check_small_file(key: str, path: Path) -> None:
    """A file the program reads whole: if it exists, a regular file of sane size (``/dev/zero``, a FIFO or a
    directory named here once hung or exhausted memory). A missing one is reported where it is needed."""
    try:
        info = path.stat()
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ConfigError(f"{key}: cannot read {path}: {exc.strerror or exc}") from None
    except ValueError:
        raise ConfigError(f"{key}: {str(path)!r} holds a NUL character, which no file name can") from None
    if not stat.S_ISREG(info.st_mode):
        raise ConfigError(f"{key}: {path} is not a regular file")
    if info.st_size > MAX_SECRET_FILE_BYTES:
        raise ConfigError(f"{key}: {path} is {info.st_size:,} bytes; a key file is a few kB")


def _check_host(key: str, host: str) -> None:
    if not host or not host.isascii() or not host.isprintable() or any(c.isspace() for c in host):
        raise ConfigError(f"{key}: {host!r} must be a host name or address in printable ASCII without spaces")


def _check_jump_host(key: str, spec: str) -> None:
    """``[user@]host[:port]`` as the SSH link reads it, checked at load (port 99999 once failed at
    connect)."""
    user, _, rest = spec.rpartition("@")
    host, colon, port_text = rest.partition(":")
    if user and (not user.isprintable() or any(c.isspace() for c in user)):
        raise ConfigError(f"{key}: the user in {spec!r} must be a login name without spaces")
    _check_host(key, host)
    if colon and not (port_text.isascii() and port_text.isdigit() and 1 <= int(port_text) <= 65535):
        raise ConfigError(f"{key}: port {port_text!r} in {spec!r} is not a TCP port (1-65535)")


def host_port(text: str, key: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[v6]:PORT`` too) split and checked; the error names ``key`` and says what is wrong."""
    host, colon, port_text = text.strip().rpartition(":")
    host = host.removeprefix("[").removesuffix("]")
    if not colon or not host or any(c.isspace() for c in host):
        raise ConfigError(f"{key}: {text!r} must be HOST:PORT, e.g. 255.255.255.255:55672")
    if not port_text.isdigit() or not 1 <= int(port_text) <= 65535:
        raise ConfigError(f"{key}: {port_text!r} in {text!r} is not a UDP port (1-65535)")
    return host, int(port_text)


BALLOON_FEED_KINDS = ("udp", "tcp", "file")


def _check_balloon_feed(feed: BalloonFeedConfig, given: set[str], key: str) -> None:
    """``given`` (the keys written in the file) catches settings that the chosen kind would silently ignore."""
    kinds = ", ".join(repr(k) for k in BALLOON_FEED_KINDS)
    if feed.kind == "":
        if given - {"kind"}:
            raise ConfigError(
                f"{key}.kind: required when [{key}] sets {', '.join(sorted(given))} (one of {kinds})"
            )
        return
    if feed.kind not in BALLOON_FEED_KINDS:
        raise ConfigError(f'{key}.kind: {feed.kind!r} is not one of {kinds} (or "" for no feed)')
    if feed.kind == "file":
        if feed.path is None:
            raise ConfigError(f"{key}.path: a file feed needs the path of the log to follow")
        for name in ("host", "port"):
            if name in given:
                raise ConfigError(f"{key}.{name}: a file feed reads {feed.path}, not the network")
        return
    if "path" in given:
        raise ConfigError(f"{key}.path: only a file feed reads a path (kind is {feed.kind!r})")
    if not feed.host or any(c.isspace() for c in feed.host):
        raise ConfigError(f"{key}.host: {feed.host!r} must be a host name or address without spaces")
    if not 1 <= feed.port <= 65535:
        protocol = feed.kind.upper()
        raise ConfigError(f"{key}.port: {feed.port} is not a {protocol} port (1-65535)")


def parse_config(document: dict[str, Any], source: Path | None = None) -> Config:
    """Build a ``Config`` from an already-parsed TOML document."""
    sections = {
        "operator": OperatorConfig,
        "data": DataConfig,
        "rockblock": RockblockConfig,
        "mo": MoConfig,
        "console": ConsoleConfig,
        "balloon_feed": BalloonFeedConfig,
        "chase": ChaseConfig,
        "server": ServerConfig,
    }
    document = dict(document)
    operators = _operators(document.pop("operator")) if isinstance(document.get("operator"), list) else ()
    if "approver" in document:
        raise ConfigError(
            "approver: the [[approver]] table was removed (ssh-agent keys no longer say who approves); the "
            'operations server\'s [[operator]] list does: docs/console.md, "One operations server"'
        )
    unknown = sorted(set(document) - set(sections) - {"capsule"})
    if unknown:
        allowed = ", ".join(sorted([*sections, "capsule"]))
        raise ConfigError(f"{unknown[0]}: unknown section (allowed: {allowed})")
    kwargs: dict[str, Any] = {
        name: _build(cls, document[name], name) for name, cls in sections.items() if name in document
    }
    _check_sections(kwargs)
    if "balloon_feed" in kwargs:
        _check_balloon_feed(kwargs["balloon_feed"], set(document["balloon_feed"]), "balloon_feed")
    raw_capsules = document.get("capsule", [])
    if not isinstance(raw_capsules, list):
        raise ConfigError("capsule: write each capsule as a [[capsule]] table")
    capsules = []
    for index, table in enumerate(raw_capsules):
        key = f"capsule[{index}]"
        capsule = _build(CapsuleConfig, table, key)
        _check_capsule(capsule, key)
        capsules.append(capsule)
    names = [c.name for c in capsules]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ConfigError(f"capsule.name: {duplicates[0]!r} is used by more than one capsule")
    return Config(**kwargs, capsules=tuple(capsules), operators=operators, source=source)


def _operators(tables: list[Any]) -> tuple[OperatorAccount, ...]:
    """``[[operator]]``: each account once, each name printable and once (an audit names them)."""
    operators = []
    for index, table in enumerate(tables):
        operator = _build(OperatorAccount, table, f"operator[{index}]")
        if not operator.account.strip() or not operator.name.strip() or not operator.name.isprintable():
            raise ConfigError(f"operator[{index}]: give the account and a printable operator name")
        operators.append(operator)
    for what in ("account", "name"):
        values = [getattr(o, what).casefold() for o in operators]
        twice = sorted({v for v in values if values.count(v) > 1})
        if twice:
            raise ConfigError(f"operator.{what}: {twice[0]!r} is listed twice in [[operator]]")
    return tuple(operators)


def load_config(path: str | Path | None = None) -> Config:
    """Read the configuration file; a missing default file gives the defaults with no capsules.

    A file named by ``--config`` or ``$DRS_CONFIG`` must exist: a typo there would otherwise run
    with no capsules and the default store, and look like lost data.
    """
    from_env = os.environ.get(CONFIG_ENV, "")
    if path is not None:
        resolved, named_by = _expand(Path(path)), "configuration file"
    elif from_env:
        resolved, named_by = _expand(Path(from_env)), f"{CONFIG_ENV}: configuration file"
    else:
        resolved, named_by = default_config_path(), ""
    try:
        present = resolved.exists()
    except OSError as exc:  # EACCES on a directory above it: a file may be there, so the defaults would lie
        raise ConfigError(
            f"{resolved}: cannot read: {exc.strerror or exc} (a directory above it cannot be entered by this account;"
            f" name a readable file with --config or ${CONFIG_ENV})"
        ) from None
    if not present:
        if named_by:
            raise ConfigError(f"{named_by} {resolved} does not exist")
        return Config()
    try:
        document = tomllib.loads(resolved.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{resolved}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{resolved}: cannot read: {exc}") from None
    return parse_config(document, source=resolved)
