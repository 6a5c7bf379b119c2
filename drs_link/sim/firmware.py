"""The capsule's microcontroller (SAMD21 firmware, drs_protocol.md §3.4–3.6) as a function of time.

The firmware is modelled by the moments that matter (relay latched, Go received) rather than by a
thread, so a test can ask "what did the Pi's serial port receive between t0 and t1" for any scaled
clock. Behaviour kept from the firmware: ~23 s boot before NMEA, one GGA+RMC pair per second
while waiting for Go, Go is any newline-terminated line containing ``GoGoGo`` in a 32-byte buffer
and only while waiting, a 31-line countdown, then Gone mode (persistent, silent to the Pi).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from datetime import datetime, timedelta

from drs_link.link import format_gga, format_rmc

BOOT_S = 23.0
COUNTDOWN_FROM = 30
SERVO_A_AFTER_GO_S = 32.0
RX_BUFFER = 32


@dataclass
class GnssSky:
    """What the simulated receiver reports; ``fix`` False is the no-fix fault."""

    fix: bool = True
    latitude: float = 67.8887
    longitude: float = 21.0856
    altitude_m: float = 31500.0
    satellites: int = 9
    hdop: float = 0.9


class Firmware:
    def __init__(self, sky: GnssSky | None = None, gone: bool = False, battery: bool = True) -> None:
        self.sky = sky or GnssSky()
        self.gone = gone
        self.battery = battery
        self.powered_at: datetime | None = None
        self.go_at: datetime | None = None
        self.servo_a_opened_at: datetime | None = None
        self._rx = bytearray()
        self._lock = threading.Lock()
        self._gone_at_power_on = gone

    def relay_latched(self, at: datetime) -> None:
        """The latching relay connected the batteries: boot starts (once per latch)."""
        with self._lock:
            if self.powered_at is None and self.battery:
                self.powered_at = at
                self._gone_at_power_on = self.gone

    def relay_reset(self, at: datetime) -> None:
        """The OFF button: batteries disconnected; a completed drop has already set the Gone flag."""
        with self._lock:
            if self.servo_a_opened_at is not None and at >= self.servo_a_opened_at:
                self.gone = True
            self.powered_at = None
            self.go_at = None
            self.servo_a_opened_at = None
            self._rx.clear()

    def state_at(self, at: datetime) -> str:
        with self._lock:
            return self._state_at(at)

    def _state_at(self, at: datetime) -> str:
        if self.powered_at is None or at < self.powered_at:
            return "off"
        if self._gone_at_power_on:
            return "gone"
        if at < self.powered_at + timedelta(seconds=BOOT_S):
            return "init_GPS"
        if self.go_at is None or at < self.go_at:
            return "pi_echo"
        if at < self.go_at + timedelta(seconds=SERVO_A_AFTER_GO_S):
            return "drop"
        return "gone"

    def receive_from_pi(self, data: bytes, at: datetime) -> None:
        """Bytes on the Pi's TX line; only a complete line seen in ``pi_echo`` can trigger Go."""
        with self._lock:
            for byte in data:
                if byte == 0x0A:
                    line = bytes(self._rx).decode("ascii", errors="replace")
                    self._rx.clear()
                    if "GoGoGo" in line and self._state_at(at) == "pi_echo":
                        self.go_at = at
                        self.servo_a_opened_at = at + timedelta(seconds=SERVO_A_AFTER_GO_S)
                elif len(self._rx) < RX_BUFFER - 1:
                    self._rx.append(byte)
                else:
                    self._rx[-1] = byte

    def output_between(self, start: datetime, end: datetime) -> list[str]:
        """Lines the Pi's serial port receives in [start, end), in order, without line endings."""
        with self._lock:
            if self.powered_at is None or end <= start:
                return []
            lines: list[str] = []
            first = max(0, math.ceil((start - self.powered_at).total_seconds()))
            last = (end - self.powered_at).total_seconds()
            second = first
            while second < last:
                at = self.powered_at + timedelta(seconds=second)
                lines.extend(self._lines_at(at))
                second += 1
            if self.go_at is not None:
                for n in range(COUNTDOWN_FROM, -1, -1):
                    at = self.go_at + timedelta(seconds=COUNTDOWN_FROM - n)
                    if start <= at < end:
                        lines.append(f"Dropping in {n} seconds!")
            return lines

    def _lines_at(self, at: datetime) -> list[str]:
        if self._state_at(at) != "pi_echo":
            return []
        sky = self.sky
        if sky.fix:
            return [
                format_gga(at, sky.latitude, sky.longitude, 1, sky.satellites, sky.hdop, sky.altitude_m),
                format_rmc(at, sky.latitude, sky.longitude),
            ]
        return [format_gga(at, None, None, 0, 0, None, None), format_rmc(at, None, None)]
