#!/usr/bin/env python3
"""The DRS Pi agent: the stock scripts' pin sequence and serial protocol, with what they lack.

Installed by the console over SFTP into the tools directory as ``drs_agent.py`` and run with
Python 3 on the Pi. It must stand alone there, so it imports only the standard library, gpiozero
(the maintained GPIO library; RPi.GPIO and the WiringPi CLI are gone from current Pi OS) and
pyserial. Compared with the stock scripts it logs NMEA continuously with UTC timestamps (a
detached logger started at power-on), and Go reads the firmware's ``Dropping in 30 seconds!``
acknowledgement, re-sending once if it is missing, instead of printing that line itself.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import signal
import subprocess
import sys
import time
from datetime import UTC, datetime
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported where the port is opened: the other commands run without pyserial
    import serial

SERIAL_LOG = "DRS_serial_log.txt"
AGENT_LOG = "drs_agent_nmea.log"
LOGGER_PIDFILE = "drs_agent_logger.pid"
SUPPLY, SET_INPUT, ENABLE_LOW, TXD = 9, 10, 2, 14
COIL_PULSE_S = 2.0
ACK = "Dropping in 30 seconds!"
ACK_WAIT_S = 2.0
ALT5_COMMANDS = (
    ("pinctrl", "set", "14", "a5"),
    ("raspi-gpio", "set", "14", "a5"),
    ("gpio", "-g", "mode", "14", "alt5"),
)


def say(text: str) -> None:
    print(text, flush=True)


def utc_stamp() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def tx_to_alt5() -> None:
    """GPIO14 back to the UART (``/etc/profile`` drives it low at every login: drs_protocol.md 2.2)."""
    for command in ALT5_COMMANDS:
        if shutil.which(command[0]):
            subprocess.run(command, check=True, timeout=10)
            say("gpio 14=alt5 (" + " ".join(command) + ")")
            return
    raise SystemExit("drs-agent: no pinctrl, raspi-gpio or gpio command to put GPIO14 into alt5")


def pulse_relay() -> None:
    """DRS_on.py's three-pin interlock: BCM9=1, BCM10=1, BCM2=0 for 2 s, then release every pin."""
    from gpiozero import DigitalOutputDevice

    supply = DigitalOutputDevice(SUPPLY, initial_value=True)
    say("gpio 9=1")
    set_input = DigitalOutputDevice(SET_INPUT, initial_value=True)
    say("gpio 10=1")
    enable = DigitalOutputDevice(ENABLE_LOW, initial_value=False)
    say("gpio 2=0")
    time.sleep(COIL_PULSE_S)
    enable.on()
    say("gpio 2=1")
    set_input.off()
    say("gpio 10=0")
    for device in (enable, set_input, supply):
        device.close()
    say("gpio released")


def _logger_pid() -> int | None:
    try:
        pid = int(open(LOGGER_PIDFILE).read().strip())
        os.kill(pid, 0)
        return pid
    except (OSError, ValueError):
        return None


def stop_logger() -> None:
    pid = _logger_pid()
    if pid is None:
        return
    os.kill(pid, signal.SIGTERM)
    for _ in range(50):
        try:
            os.kill(pid, 0)
        except OSError:
            break
        time.sleep(0.05)
    try:
        os.remove(LOGGER_PIDFILE)
    except OSError:
        pass


def start_logger(serial_device: str) -> None:
    if _logger_pid() is not None:
        return
    with open(os.devnull, "rb") as null_in, open(os.devnull, "wb") as null_out:
        process = subprocess.Popen(
            [sys.executable, os.path.abspath(__file__), "log", "--serial", serial_device],
            stdin=null_in,
            stdout=null_out,
            stderr=null_out,
            start_new_session=True,
        )
    with open(LOGGER_PIDFILE, "w") as pidfile:
        pidfile.write(f"{process.pid}\n")


def _open_port(serial_device: str) -> serial.Serial:
    import serial

    return serial.Serial(serial_device, 9600, timeout=1)


def _record(line: bytes) -> str:
    """Append one received line to both logs; returns it as text."""
    with open(SERIAL_LOG, "ab") as raw:
        raw.write(line)
    text = line.decode("ascii", errors="replace").rstrip("\r\n")
    with open(AGENT_LOG, "a") as log:
        log.write(f"{utc_stamp()} {text}\n")
    return text


def cmd_power_on(args: argparse.Namespace) -> int:
    size = os.path.getsize(AGENT_LOG) if os.path.exists(AGENT_LOG) else 0
    say(f"drs-log-offset {size}")
    pulse_relay()
    tx_to_alt5()
    start_logger(args.serial)
    say("logger started")
    return 0


def cmd_log(args: argparse.Namespace) -> int:
    running = True

    def stop(*_: object) -> None:
        nonlocal running
        running = False

    signal.signal(signal.SIGTERM, stop)
    port = _open_port(args.serial)
    while running:
        line = port.readline()
        if line:
            _record(line)
    port.close()
    return 0


def cmd_read(args: argparse.Namespace) -> int:
    if not os.path.exists(AGENT_LOG):
        return 0
    with open(AGENT_LOG, "rb") as log:
        log.seek(max(args.offset, 0))
        sys.stdout.write(log.read()[-65536:].decode("ascii", errors="replace"))
    return 0


def cmd_go(args: argparse.Namespace) -> int:
    stop_logger()
    tx_to_alt5()
    port = _open_port(args.serial)
    acknowledged = False
    for attempt in (1, 2):
        port.write(b"\nGoGoGo\n")
        port.flush()
        say(f"GoGoGo written (attempt {attempt})")
        deadline = time.monotonic() + ACK_WAIT_S
        while time.monotonic() < deadline and not acknowledged:
            line = port.readline()
            if line and ACK in _record(line):
                acknowledged = True
        if acknowledged:
            break
    port.close()
    if not acknowledged:
        # Unlike DRS_GoGoGo.py, stay up: a Go the firmware did not take can then be retried.
        say("NO ACK from the microcontroller; the Pi stays up")
        return 3
    say(f"ACK {ACK}")
    say("Shutting down...")
    time.sleep(1.0)
    subprocess.run(shlex.split(args.shutdown_command), check=False)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="drs_agent.py", description="DRS Pi agent")
    commands = parser.add_subparsers(dest="command", required=True)
    power = commands.add_parser("power-on")
    power.add_argument("--serial", required=True)
    power.set_defaults(func=cmd_power_on)
    log = commands.add_parser("log")
    log.add_argument("--serial", required=True)
    log.set_defaults(func=cmd_log)
    read = commands.add_parser("read")
    read.add_argument("--offset", type=int, default=0)
    read.set_defaults(func=cmd_read)
    go = commands.add_parser("go")
    go.add_argument("--serial", required=True)
    go.add_argument("--shutdown-command", default="sudo shutdown now")
    go.set_defaults(func=cmd_go)
    args = parser.parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
