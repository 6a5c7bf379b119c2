"""Queue an MT at the RockBLOCK gateway without ever sending a command twice (drs_protocol.md 4.1).

A request is re-sent only when the previous attempt provably never reached the gateway (the TCP
or TLS connection could not be opened, so not one byte of the request was written). Once the
request has been written, any failure leaves the delivery *unknown*: the gateway may have queued
it, and a second copy could, for PARACHUTE, fire twice or be consumed at a later cycle. The
credentials travel only in the form body, never in the URL, a log line or an error text.
"""

from __future__ import annotations

import http.client
import logging
import os
import ssl
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from urllib.parse import urlencode, urlsplit

from drs_link.config import RockblockConfig
from drs_link.errors import ConfigError
from drs_link.redaction import redact, secret_forms

log = logging.getLogger(__name__)

FAILURE_MEANINGS: dict[int, str] = {
    10: "invalid login credentials",
    11: "no RockBLOCK with this IMEI on the account",
    12: "no line rental",
    13: "insufficient credit",
    14: "could not decode hex",
    15: "data too long",
    16: "no data",
    99: "system error",
}
FLUSH_WARNING = (
    "flush=yes empties this modem's whole MT queue at the gateway: every command queued and not yet "
    "downloaded is deleted; whether the new message survives the flush is not documented"
)
LOOPBACK_HOSTS = frozenset({"127.0.0.1", "localhost", "::1"})
MAX_REPLY_BYTES = 4096


@dataclass(frozen=True)
class SendResult:
    """What is known after one send: ``queued`` (mt_id), ``failed`` (code), ``unknown`` or ``not_sent``."""

    status: str
    detail: str
    mt_id: int | None = None
    code: int | None = None
    attempts: int = 1

    @property
    def may_be_queued(self) -> bool:
        return self.status in ("queued", "unknown")


def resolve_password(config: RockblockConfig, environ: Mapping[str, str] | None = None) -> str:
    """The portal password from the named environment variable, else the OS keyring; never from argv."""
    environ = os.environ if environ is None else environ
    if config.password_env and environ.get(config.password_env):
        return environ[config.password_env]
    if config.keyring_service:
        import keyring
        from keyring.errors import KeyringError

        try:
            secret = keyring.get_password(config.keyring_service, config.username)
        except KeyringError as exc:
            raise ConfigError(
                f"rockblock.keyring_service: the OS keyring failed ({type(exc).__name__})"
            ) from None
        if secret:
            return secret
    where = (
        f"the environment variable {config.password_env}"
        if config.password_env
        else "no environment variable"
    )
    if config.keyring_service:
        where += f" or the keyring service {config.keyring_service!r} (user {config.username!r})"
    raise ConfigError(f"no RockBLOCK password found: set {where}")


def check_mt_url(url: str) -> None:
    """Refuse endpoints that would leak credentials (userinfo, query) or send them unencrypted."""
    parts = urlsplit(url)
    if parts.scheme not in ("https", "http") or not parts.hostname:
        raise ConfigError(f"rockblock.mt_url: {url!r} is not an http(s) URL")
    if parts.username or parts.password or parts.query or parts.fragment:
        raise ConfigError("rockblock.mt_url: must not carry credentials, a query or a fragment")
    if parts.scheme == "http" and parts.hostname not in LOOPBACK_HOSTS:
        raise ConfigError("rockblock.mt_url: plain http is only allowed to a loopback simulator; use https")


class RockblockGateway:
    """The MT endpoint of one RockBLOCK account."""

    def __init__(
        self,
        url: str,
        username: str,
        password: str,
        timeout_s: float = 20.0,
        connect_attempts: int = 3,
        retry_delay_s: float = 1.0,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        check_mt_url(url)
        if not username:
            raise ConfigError("rockblock.username: required to send commands")
        self._url = urlsplit(url)
        self._username = username
        self._password = password
        self._secret_forms = secret_forms(password, username)
        self._timeout_s = timeout_s
        self._connect_attempts = max(1, connect_attempts)
        self._retry_delay_s = retry_delay_s
        self._sleep = sleep

    @classmethod
    def from_config(
        cls, config: RockblockConfig, environ: Mapping[str, str] | None = None
    ) -> RockblockGateway:
        return cls(config.mt_url, config.username, resolve_password(config, environ), config.timeout_s)

    def _redact(self, text: str) -> str:
        return redact(text, self._secret_forms)

    def _connection(self) -> http.client.HTTPConnection:
        host, port = self._url.hostname or "", self._url.port
        if self._url.scheme == "https":
            return http.client.HTTPSConnection(
                host, port, timeout=self._timeout_s, context=ssl.create_default_context()
            )
        return http.client.HTTPConnection(host, port, timeout=self._timeout_s)

    def send(self, imei: str, payload: bytes, flush: bool = False) -> SendResult:
        form = {
            "imei": imei,
            "username": self._username,
            "password": self._password,
            "data": payload.hex().upper(),
        }
        if flush:
            form["flush"] = "yes"
        body = urlencode(form).encode("ascii")
        headers = {"Content-Type": "application/x-www-form-urlencoded", "Accept": "text/plain"}
        last_failure = ""
        for attempt in range(1, self._connect_attempts + 1):
            conn = self._connection()
            try:
                conn.connect()
            except (OSError, ssl.SSLError) as exc:
                conn.close()
                last_failure = self._redact(f"{type(exc).__name__}: {exc}")
                log.warning("RockBLOCK connect attempt %d failed, nothing sent: %s", attempt, last_failure)
                if attempt < self._connect_attempts:
                    self._sleep(self._retry_delay_s * attempt)
                continue
            try:
                conn.request("POST", self._url.path or "/", body=body, headers=headers)
                response = conn.getresponse()
                reply = response.read(MAX_REPLY_BYTES).decode("utf-8", "replace")
            except (OSError, http.client.HTTPException) as exc:
                reason = self._redact(f"{type(exc).__name__}: {exc}".rstrip(": "))
                return SendResult(
                    "unknown",
                    f"the connection failed after the request was written ({reason}): the command may or may "
                    "not be queued and is NOT re-sent; check the RockBLOCK portal before sending anything "
                    "again",
                    attempts=attempt,
                )
            finally:
                conn.close()
            return self._interpret(response.status, self._redact(reply), attempt)
        return SendResult(
            "not_sent",
            f"the gateway could not be reached in {self._connect_attempts} attempts, nothing was sent "
            f"(last: {last_failure})",
            attempts=self._connect_attempts,
        )

    @staticmethod
    def _interpret(status: int, reply: str, attempts: int) -> SendResult:
        text = reply.strip()
        parts = text.split(",", 2)
        if parts[0] == "OK" and len(parts) == 2 and parts[1].isdigit():
            return SendResult(
                "queued", f"queued at the gateway as MT {parts[1]}", mt_id=int(parts[1]), attempts=attempts
            )
        if parts[0] == "FAILED" and len(parts) >= 2 and parts[1].strip().isdigit():
            code = int(parts[1])
            meaning = FAILURE_MEANINGS.get(code, "undocumented code")
            said = parts[2].strip() if len(parts) == 3 else ""
            return SendResult(
                "failed",
                f"gateway refused it: FAILED {code} ({meaning}){': ' + said if said else ''}",
                code=code,
                attempts=attempts,
            )
        return SendResult(
            "unknown",
            f"the gateway answered HTTP {status} with an unrecognised reply {text[:80]!r}: "
            "the command may or may not be queued and is NOT re-sent",
            attempts=attempts,
        )
