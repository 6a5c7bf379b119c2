"""The landing strip as files: GeoJSON for tools, KML for Google Earth.

The strip is the line of central landings in candidate order ("roughly underneath the future path
of the balloon", as the DRS paper puts it), with each candidate's landing as a point coloured by
go/no-go, the balloon's future path, and the recommended candidate's ellipses. Demo weather is
named in the document title and properties, as every other output does.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import simplekml

from predictor.errors import PredictorError
from predictor.landing import wrap_lon
from predictor.planning.sweep import Candidate, ReleasePlan
from predictor.prediction import iso_z

DEMO_LABEL = "DEMO WEATHER, NOT A FORECAST"
GO_COLOUR = "ff00c000"
NO_GO_COLOUR = "ff0000ff"


def _recommended(plan: ReleasePlan) -> Candidate | None:
    return plan.candidates[plan.windows[0].recommended] if plan.windows else None


def _landed(plan: ReleasePlan) -> list[Candidate]:
    return [c for c in plan.candidates if c.status is None]


def _balloon_coords(plan: ReleasePlan) -> list[tuple[float, float]]:
    b = plan.balloon
    return [
        (float(wrap_lon(lo)), float(la)) for la, lo in zip(b.lat, b.lon, strict=True) if math.isfinite(la)
    ]


def to_geojson(plan: ReleasePlan) -> dict[str, Any]:
    features: list[dict[str, Any]] = [
        {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": [list(p) for p in _balloon_coords(plan)]},
            "properties": {"kind": "balloon path"},
        }
    ]
    landed = _landed(plan)
    if len(landed) >= 2:
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "LineString",
                    "coordinates": [[c.landing_lon, c.landing_lat] for c in landed],
                },
                "properties": {"kind": "landing strip"},
            }
        )
    for c in landed:
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [c.landing_lon, c.landing_lat]},
                "properties": {
                    "kind": "candidate landing",
                    "release_time": iso_z(c.release_time),
                    "go": c.go,
                    "reasons": list(c.reasons),
                    "zone_probability": c.zone_probability,
                    "expected_target_km": c.expected_target_km,
                    "sigma_major_km": c.sigma_major_km,
                },
            }
        )
    best = _recommended(plan)
    if best is not None and best.ellipse is not None:
        for contour in best.ellipse.contours:
            features.append(
                {
                    "type": "Feature",
                    "geometry": {
                        "type": "Polygon",
                        "coordinates": [[list(p) for p in best.ellipse.outline(contour)]],
                    },
                    "properties": {
                        "kind": "recommended ellipse",
                        "release_time": iso_z(best.release_time),
                        "probability": contour.probability,
                        "n_sigma": contour.n_sigma,
                    },
                }
            )
    return {
        "type": "FeatureCollection",
        "properties": {
            "title": ("DRS release window" + (f" ({DEMO_LABEL})" if plan.is_demo else "")),
            "verdict": plan.verdict,
            "weather": plan.weather_source,
            "is_demo": plan.is_demo,
        },
        "features": features,
    }


def to_kml(plan: ReleasePlan) -> str:
    kml = simplekml.Kml(name="DRS release window" + (f" ({DEMO_LABEL})" if plan.is_demo else ""))
    kml.document.description = "\n".join([plan.verdict, f"Weather: {plan.weather_source}", *plan.warnings])
    balloon = kml.newlinestring(name="balloon path", coords=_balloon_coords(plan))
    balloon.style.linestyle.color = "ffffffff"
    landed = _landed(plan)
    if len(landed) >= 2:
        strip = kml.newlinestring(
            name="landing strip", coords=[(c.landing_lon, c.landing_lat) for c in landed]
        )
        strip.style.linestyle.width = 3
        strip.style.linestyle.color = "ff00ffff"
    folder = kml.newfolder(name="candidates")
    for c in landed:
        point = folder.newpoint(name=iso_z(c.release_time)[11:16], coords=[(c.landing_lon, c.landing_lat)])
        point.style.iconstyle.color = GO_COLOUR if c.go else NO_GO_COLOUR
        point.style.iconstyle.scale = 0.6
        point.description = "GO" if c.go else "NO-GO: " + "; ".join(c.reasons)
    best = _recommended(plan)
    if best is not None and best.ellipse is not None:
        for contour in best.ellipse.contours:
            ring = kml.newlinestring(
                name=f"recommended {iso_z(best.release_time)}: {100 * contour.probability:.1f} % ellipse",
                coords=best.ellipse.outline(contour),
            )
            ring.style.linestyle.color = GO_COLOUR
    return str(kml.kml())


def _write(path: str | Path, text: str, what: str) -> Path:
    out = Path(path)
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise PredictorError(f"cannot write the {what} to {out}: {exc.strerror or exc}") from None
    return out


def write_geojson(plan: ReleasePlan, path: str | Path) -> Path:
    return _write(path, json.dumps(to_geojson(plan), indent=1, ensure_ascii=False), "GeoJSON")


def write_kml(plan: ReleasePlan, path: str | Path) -> Path:
    return _write(path, to_kml(plan), "KML")
