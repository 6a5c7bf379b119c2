"""The Pi's GPIO as DRS_on.py drives it, enforcing the three-pin interlock of drs_protocol.md §2.3.

The relay's SET coil is energised only while BCM9 (NOR-gate supply) is a high output, BCM10 is a
high output and BCM2 is a low output, all at once; a pulse shorter than ``MIN_PULSE_S`` does not
latch it. Nothing here can reset the relay: on the real board only the OFF button can.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from drs_link.sim.firmware import Firmware

MIN_PULSE_S = 0.5
SUPPLY, SET_INPUT, ENABLE_LOW, TXD = 9, 10, 2, 14


class FakeGpio:
    def __init__(self, firmware: Firmware, clock: Callable[[], datetime]) -> None:
        self.firmware = firmware
        self.clock = clock
        self.outputs: dict[int, int] = {}
        self.tx_mode = "out-low"
        self.relay_latched = False
        self._coil_since: datetime | None = None

    def _coil_energised(self) -> bool:
        o = self.outputs
        return o.get(SUPPLY) == 1 and o.get(SET_INPUT) == 1 and o.get(ENABLE_LOW) == 0

    def _update(self) -> None:
        now = self.clock()
        if self._coil_energised():
            if self._coil_since is None:
                self._coil_since = now
            return
        if self._coil_since is not None:
            if (now - self._coil_since).total_seconds() >= MIN_PULSE_S:
                self.relay_latched = True
                self.firmware.relay_latched(self._coil_since)
            self._coil_since = None

    def output(self, pin: int, level: int) -> None:
        self.outputs[pin] = 1 if level else 0
        self._update()

    def cleanup(self) -> None:
        """RPi.GPIO.cleanup(): every pin back to an input (unpowering the NOR gate)."""
        self.outputs.clear()
        self._update()

    def set_tx_mode(self, mode: str) -> None:
        """``gpio -g mode 14 alt5`` / ``out``: only in alt5 do bytes reach the microcontroller."""
        self.tx_mode = mode
