"""A prediction as files other tools open: JSON (the result document), KML (Google Earth), GeoJSON,
and GPX (a handheld loaded before the drop).

Every output built on demo weather says so where a person will see it: the KML document name and
description, every GeoJSON feature's properties, the GPX waypoint names, and the JSON's
``is_demo`` and first warning.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from predictor.geofiles import DEMO_LABEL, geojson, gpx, line_parts, polygon_parts, position, write_text
from predictor.prediction.landings import EnsemblePrediction, Prediction
from predictor.prediction.uncertainty import Ellipse

# KML colours are aabbggrr.
_ELLIPSE_COLOURS = ("ff00ffff", "ff00a5ff", "ff0000ff")
_EMPIRICAL_COLOUR = "ffff00ff"
_PATH_COLOUR = "ffffffff"


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


def _ellipses(result: Prediction | EnsemblePrediction) -> list[tuple[Ellipse, tuple[str, ...]]]:
    ellipses: list[tuple[Ellipse, tuple[str, ...]]] = [(_central(result).ellipse, _ELLIPSE_COLOURS)]
    if isinstance(result, EnsemblePrediction):
        ellipses.append((result.empirical, (_EMPIRICAL_COLOUR,)))
    return ellipses


def _path(pred: Prediction) -> list[tuple[float, float, float]]:
    track = pred.track
    return [
        (float(lo), float(la), float(z)) for lo, la, z in zip(track.lon, track.lat, track.alt_m, strict=True)
    ]


def to_kml(result: Prediction | EnsemblePrediction) -> str:
    # fastkml is imported here, when a KML is asked for: it costs ~50 ms, which every `drs predict`
    # paid before writing its JSON.
    from predictor.geofiles import kml

    pred = _central(result)
    styles = [kml.style("path", _PATH_COLOUR, width=3)]
    contents: list[kml.Feature] = [
        kml.line("descent path", line_parts(_path(pred)), "path", absolute=True),
        kml.point("release", position((pred.release.lon, pred.release.lat, pred.release.alt_m)),
                  description=pred.release.to_dict()["time"], absolute=True),
        kml.point("landing", position((pred.landing.lon, pred.landing.lat)),
                  description=f"{pred.landing.to_dict()['time']}, {pred.landing.alt_m:.0f} m"),
    ]  # fmt: skip
    if isinstance(result, EnsemblePrediction):
        points = zip(result.member_lon, result.member_lat, strict=True)
        contents.append(
            kml.folder(f"{result.members} ensemble landings", [kml.point(None, position(p)) for p in points])
        )
    for j, (ellipse, colours) in enumerate(_ellipses(result)):
        for i, contour in enumerate(ellipse.contours):
            style_id = f"ellipse{j}-contour{i}"
            styles.append(kml.style(style_id, colours[min(i, len(colours) - 1)], width=2))
            contents.append(
                kml.polygon(_contour_label(ellipse, i), polygon_parts(ellipse.outline(contour)), style_id)
            )
    return kml.document(_title(pred), _description(pred), styles, contents)


def _provenance(pred: Prediction) -> geojson.Provenance:
    return geojson.Provenance(_title(pred), pred.weather_source, pred.is_demo)


def to_geojson(result: Prediction | EnsemblePrediction) -> dict[str, Any]:
    pred = _central(result)
    about = _provenance(pred)
    release, landing = pred.release, pred.landing
    features = [
        geojson.feature(geojson.line(_path(pred)), "path", about),
        geojson.feature(geojson.point((release.lon, release.lat)), "release", about, **release.to_dict()),
        geojson.feature(geojson.point((landing.lon, landing.lat)), "landing", about, **landing.to_dict()),
    ]
    if isinstance(result, EnsemblePrediction):
        members = geojson.multipoint(list(zip(result.member_lon, result.member_lat, strict=True)))
        features.append(geojson.feature(members, "ensemble landings", about, members=result.members))
    for ellipse, _ in _ellipses(result):
        for contour in ellipse.contours:
            ring = geojson.polygon(ellipse.outline(contour))
            features.append(
                geojson.feature(ring, "ellipse", about, ellipse=ellipse.kind, **contour.to_dict())
            )
    return geojson.collection(features, about, warnings=list(pred.warnings))


def to_gpx(result: Prediction | EnsemblePrediction) -> str:
    """The predicted landing and the release as waypoints, and the descent path as a track.

    The landing waypoint is what a recovery team loads into a handheld before the drop; its name
    says DEMO when the weather was, since the name is all a handheld shows.
    """
    pred = _central(result)
    release, landing = pred.release, pred.landing
    prefix = "DEMO" if pred.is_demo else "DRS"
    e = pred.ellipse.contours[0]
    waypoints = [
        gpx.Waypoint(landing.lat, landing.lon, landing.alt_m, gpx.short_name(prefix, "PRED LAND"),
                     gpx.PREDICTED_LANDING_SYMBOL,
                     f"{_title(pred)}: predicted landing; {100 * e.probability:.0f} % ellipse, semi-axes "
                     f"{e.semi_major_km:.1f} x {e.semi_minor_km:.1f} km", landing.time),
        gpx.Waypoint(release.lat, release.lon, release.alt_m, gpx.short_name(prefix, "RELEASE"),
                     gpx.RELEASE_SYMBOL, f"{_title(pred)}: release", release.time),
    ]  # fmt: skip
    path = [gpx.TrackPoint(la, lo, z) for lo, la, z in _path(pred)]
    return gpx.to_gpx(_title(pred), waypoints, [(f"{prefix} predicted descent", path)])


def write_kml(result: Prediction | EnsemblePrediction, path: str | Path) -> Path:
    return write_text(path, to_kml(result), "KML")


def write_geojson(result: Prediction | EnsemblePrediction, path: str | Path) -> Path:
    return write_text(path, geojson.dumps(to_geojson(result)), "GeoJSON")


def write_gpx(result: Prediction | EnsemblePrediction, path: str | Path) -> Path:
    return write_text(path, to_gpx(result), "GPX")


def write_json(result: Prediction | EnsemblePrediction, path: str | Path, track: bool = False) -> Path:
    return write_text(path, to_json(result, track=track), "JSON")
