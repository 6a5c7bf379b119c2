"""How one capsule's telemetry reads in a table cell: value, age, and STALE in words when it is old.

Kept apart from the widgets so that every screen words a value the same way; the cells are Rich
``Text`` with a style class (ok/warn/bad/stale), but the words alone carry the meaning.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from rich.text import Text

from drs_link.fleet import CapsuleTelemetry
from drs_link.staleness import STALE_GLYPH, Freshness, Reading, format_age

STYLE = {"ok": "green", "warn": "yellow", "bad": "bold red", "stale": "magenta", "none": "dim"}


def _cell(reading: Reading[dict[str, Any]], now: datetime, text: str, level: str) -> Text:
    state = reading.freshness(now)
    if state is Freshness.MISSING:
        return Text("—", style=STYLE["none"])
    age = format_age(reading.age_s(now) or 0.0)
    if state is Freshness.STALE:
        return Text(f"{STALE_GLYPH}STALE {text} {age}", style=STYLE["stale"])
    return Text(f"{text} {age}", style=STYLE[level])


def link_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("link")
    up = reading.value.get("up") if reading.value else None
    return _cell(reading, now, "UP" if up else "DOWN", "ok" if up else "bad")


def release_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("release")
    state = reading.value.get("state", "?") if reading.value else "?"
    level = {"idle": "none", "powered": "warn", "released": "ok"}.get(state, "warn")
    text = state.upper()
    if state == "powered":
        text += " NMEA" if reading.value and reading.value.get("nmea_seen") else " no-NMEA"
    return _cell(reading, now, text, "ok" if level == "none" else level)


def gnss_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("gnss")
    v = reading.value or {}
    if v.get("has_fix"):
        hdop = v.get("hdop")
        text = f"FIX {v.get('sats')}sv H{hdop:.1f}" if hdop is not None else f"FIX {v.get('sats')}sv"
        return _cell(reading, now, text, "ok")
    return _cell(reading, now, f"NO FIX {v.get('sats') or 0}sv", "bad")


def storage_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("storage")
    v = reading.value or {}
    total, used = v.get("total_bytes"), v.get("used_bytes")
    raid = str(v.get("raid", "?"))
    if total:
        free_gb = (total - used) / 1e9
        text = f"{used / 1e9:.1f}/{total / 1e9:.0f}GB {free_gb:.0f}free {raid}"
    else:
        text = f"? {raid}"
    return _cell(reading, now, text, "ok" if raid == "healthy" else "bad")


def sync_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("sync")
    v = reading.value or {}
    fraction = v.get("fraction")
    if fraction is None:
        return _cell(reading, now, "?", "warn")
    text = f"{fraction * 100:.0f}%"
    if v.get("bytes_pending"):
        text += f" {v['bytes_pending'] / 1e6:.1f}MB left"
    return _cell(reading, now, text, "ok" if fraction >= 1.0 else "warn")


def report_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("report")
    v = reading.value or {}
    if not v:
        return Text("—", style=STYLE["none"])
    vbat = v.get("vbat")
    alt = v.get("alt_m")
    text = f"{vbat:.2f}V" if vbat is not None else "?V"
    text += f" {alt / 1000:.1f}km" if alt is not None else " no-fix"
    if v.get("landed"):
        text += " LANDED"
    return _cell(reading, now, text, "bad" if vbat is not None and vbat < 6.5 else "ok")


def prediction_cell(t: CapsuleTelemetry, now: datetime) -> Text:
    reading = t.reading("prediction")
    v = reading.value or {}
    if not v:
        return Text("—", style=STYLE["none"])
    text = (
        f"{v['landing_lat']:.3f},{v['landing_lon']:.3f} "
        f"σ∥{v['sigma_par_km']:.1f} σ⊥{v['sigma_perp_km']:.1f}km d{v['distance_km']:.0f}km"
    )
    return _cell(reading, now, text, "ok")


COLUMNS = (
    ("Capsule", None, 8),
    ("Link", link_cell, 12),
    ("Release", release_cell, 20),
    ("GNSS", gnss_cell, 22),
    ("Storage", storage_cell, 30),
    ("Sync", sync_cell, 20),
    ("Battery/last MO", report_cell, 26),
    ("Prediction (landing, 1σ, dist)", prediction_cell, 50),
)
"""Title, cell renderer and width of each fleet column (ages widen a cell, hence the room)."""
