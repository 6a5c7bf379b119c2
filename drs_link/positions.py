"""The operator's own position: typed as ``LAT,LON``, or read from the local gpsd.

Its own module because it is the operator's process that knows where the team is (its gpsd, its
keyboard): a client of the operations server reads it here and sends the numbers (``drs recovery``),
without importing the Iridium rooms the server reads the reports with.
"""

from __future__ import annotations

import json
import math
import socket

from drs_link.errors import LinkError

GPSD_ADDRESS = ("127.0.0.1", 2947)


def parse_position(text: str) -> tuple[float, float]:
    """``LAT,LON`` in decimal degrees, as an operator types it."""
    parts = text.replace(" ", "").split(",")
    try:
        lat, lon = float(parts[0]), float(parts[1])
    except (ValueError, IndexError):
        raise LinkError(f"position {text!r} must be LAT,LON in decimal degrees, e.g. 46.52,6.63") from None
    if len(parts) != 2 or not (-90 <= lat <= 90 and -180 <= lon <= 180) or math.isnan(lat + lon):
        raise LinkError(f"position {text!r} must be LAT,LON with -90<=LAT<=90 and -180<=LON<=180")
    return lat, lon


def read_gpsd_position(
    address: tuple[str, int] = GPSD_ADDRESS, timeout_s: float = 5.0
) -> tuple[float, float]:
    """The team's own position from a local gpsd (JSON protocol): the first TPV with a 2-D or 3-D fix."""
    try:
        sock = socket.create_connection(address, timeout=timeout_s)
    except OSError as exc:
        raise LinkError(
            f"no gpsd at {address[0]}:{address[1]} ({exc.strerror or exc}): "
            "give the position with --from LAT,LON"
        ) from None
    with sock, sock.makefile("rwb") as stream:
        try:
            stream.write(b'?WATCH={"enable":true,"json":true};\n')
            stream.flush()
            for line in stream:
                try:
                    message = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if message.get("class") == "TPV" and message.get("mode", 0) >= 2 and "lat" in message:
                    return float(message["lat"]), float(message["lon"])
        except (OSError, ValueError) as exc:
            raise LinkError(
                f"gpsd at {address[0]}:{address[1]} gave no fix within {timeout_s:g} s ({type(exc).__name__})"
            ) from None
    raise LinkError(f"gpsd at {address[0]}:{address[1]} closed the connection without a fix")
