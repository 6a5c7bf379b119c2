"""A prediction as files other tools open: JSON (the result document), KML (Google Earth), GeoJSON.

Every output built on demo weather says so where a person will see it: the KML document name and
description, the GeoJSON's top-level properties, and the JSON's ``is_demo`` and first warning.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import simplekml

from predictor.errors import PredictorError
from predictor.prediction import EnsemblePrediction, Prediction
from predictor.uncertainty import Ellipse

DEMO_LABEL = "DEMO WEATHER, NOT A FORECAST"
# KML colours are aabbggrr.
_ELLIPSE_COLOURS = ("ff00ffff", "ff00a5ff", "ff0000ff")
_EMPIRICAL_COLOUR = "ffff00ff"


def _central(result: Prediction | EnsemblePrediction) -> Prediction:
    return result.central if isinstance(result, EnsemblePrediction) else result


def to_json(result: Prediction | EnsemblePrediction, track: bool = False) -> str:
    return json.dumps(result.to_dict(track=track), indent=2, ensure_ascii=False)


def _title(pred: Prediction) -> str:
    title = f"DRS landing prediction {pred.release.to_dict()['time']}"
    return f"{title} ({DEMO_LABEL})" if pred.is_demo else title


def _description(pred: Prediction) -> str:
    lines = [
        f"Weather: {pred.weather_source}",
        f"Payload: {pred.payload.name} {pred.payload.mass_kg} kg, Cd·A {pred.payload.cda_m2} m²",
        f"Descent {pred.descent_s / 60:.1f} min, drift {pred.drift_km:.1f} km, "
        f"⟨t_future⟩ {pred.t_future_mean_h:.1f} h",
        *pred.warnings,
    ]
    return "\n".join(lines)


def _contour_label(ellipse: Ellipse, index: int) -> str:
    c = ellipse.contours[index]
    return f"{ellipse.kind} {c.n_sigma:.2f}σ ({100 * c.probability:.1f} %)"


def to_kml(result: Prediction | EnsemblePrediction) -> str:
    pred = _central(result)
    kml = simplekml.Kml(name=_title(pred))
    kml.document.description = _description(pred)
    path = kml.newlinestring(
        name="descent path",
        coords=[
            (float(lo), float(la), float(z))
            for lo, la, z in zip(pred.track.lon, pred.track.lat, pred.track.alt_m, strict=True)
        ],
    )
    path.altitudemode = simplekml.AltitudeMode.absolute
    path.style.linestyle.width = 3
    release = kml.newpoint(name="release", coords=[(pred.release.lon, pred.release.lat, pred.release.alt_m)])
    release.altitudemode = simplekml.AltitudeMode.absolute
    release.description = pred.release.to_dict()["time"]
    landing = kml.newpoint(name="landing", coords=[(pred.landing.lon, pred.landing.lat, pred.landing.alt_m)])
    landing.description = f"{pred.landing.to_dict()['time']}, {pred.landing.alt_m:.0f} m"
    ellipses = [(pred.ellipse, _ELLIPSE_COLOURS)]
    if isinstance(result, EnsemblePrediction):
        ellipses.append((result.empirical, (_EMPIRICAL_COLOUR,) * 3))
        folder = kml.newfolder(name=f"{result.members} ensemble landings")
        for lat, lon in zip(result.member_lat, result.member_lon, strict=True):
            folder.newpoint(coords=[(float(lon), float(lat))])
    for ellipse, colours in ellipses:
        for i, contour in enumerate(ellipse.contours):
            polygon = kml.newpolygon(
                name=_contour_label(ellipse, i), outerboundaryis=ellipse.outline(contour)
            )
            polygon.style.linestyle.color = colours[min(i, len(colours) - 1)]
            polygon.style.linestyle.width = 2
            polygon.style.polystyle.fill = 0
    return kml.kml()


def to_geojson(result: Prediction | EnsemblePrediction) -> dict[str, Any]:
    pred = _central(result)
    features: list[dict[str, Any]] = [
        {
            "type": "Feature",
            "geometry": {
                "type": "LineString",
                "coordinates": [
                    [float(lo), float(la), float(z)]
                    for lo, la, z in zip(pred.track.lon, pred.track.lat, pred.track.alt_m, strict=True)
                ],
            },
            "properties": {"kind": "path"},
        },
        _point("release", pred.release.lon, pred.release.lat, pred.release.to_dict()),
        _point("landing", pred.landing.lon, pred.landing.lat, pred.landing.to_dict()),
    ]
    ellipses = [pred.ellipse]
    if isinstance(result, EnsemblePrediction):
        ellipses.append(result.empirical)
        features.append(
            {
                "type": "Feature",
                "geometry": {
                    "type": "MultiPoint",
                    "coordinates": [
                        [float(lo), float(la)]
                        for la, lo in zip(result.member_lat, result.member_lon, strict=True)
                    ],
                },
                "properties": {"kind": "ensemble landings", "members": result.members},
            }
        )
    for ellipse in ellipses:
        for contour in ellipse.contours:
            features.append(
                {
                    "type": "Feature",
                    "geometry": {
                        "type": "Polygon",
                        "coordinates": [[list(p) for p in ellipse.outline(contour)]],
                    },
                    "properties": {"kind": "ellipse", "ellipse": ellipse.kind, **contour.to_dict()},
                }
            )
    properties = {
        "title": _title(pred),
        "is_demo": pred.is_demo,
        "weather_source": pred.weather_source,
        "warnings": list(pred.warnings),
    }
    return {"type": "FeatureCollection", "properties": properties, "features": features}


def _point(kind: str, lon: float, lat: float, properties: dict[str, Any]) -> dict[str, Any]:
    return {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": [lon, lat]},
        "properties": {"kind": kind, **properties},
    }


def _write(path: str | Path, text: str, what: str) -> Path:
    out = Path(path)
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise PredictorError(f"cannot write the {what} file {out}: {exc.strerror or exc}") from exc
    return out


def write_kml(result: Prediction | EnsemblePrediction, path: str | Path) -> Path:
    return _write(path, to_kml(result), "KML")


def write_geojson(result: Prediction | EnsemblePrediction, path: str | Path) -> Path:
    return _write(path, json.dumps(to_geojson(result), indent=1), "GeoJSON")


def write_json(result: Prediction | EnsemblePrediction, path: str | Path, track: bool = False) -> Path:
    return _write(path, to_json(result, track=track), "JSON")
