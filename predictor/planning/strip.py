"""The landing strip as files: GeoJSON for tools, KML for Google Earth.

The strip is the line of central landings in candidate order ("roughly underneath the future path
of the balloon", as the DRS paper puts it), with each candidate's landing as a point coloured by
go/no-go, the balloon's future path, and the recommended candidate's ellipses. Demo weather is
named in the document title and in every feature's properties, as every other output does.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from predictor.geofiles import DEMO_LABEL, geojson, kml, line_parts, polygon_parts, position, write_text
from predictor.planning.sweep import Candidate, ReleasePlan
from predictor.prediction import iso_z

GO_COLOUR = "ff00c000"
NO_GO_COLOUR = "ff0000ff"
STRIP_COLOUR = "ff00ffff"
BALLOON_COLOUR = "ffffffff"


def _recommended(plan: ReleasePlan) -> Candidate | None:
    return plan.candidates[plan.windows[0].recommended] if plan.windows else None


def _landed(plan: ReleasePlan) -> list[Candidate]:
    return [c for c in plan.candidates if c.status is None]


def _balloon_path(plan: ReleasePlan) -> list[tuple[float, float]]:
    b = plan.balloon
    return [(float(lo), float(la)) for la, lo in zip(b.lat, b.lon, strict=True) if math.isfinite(la)]


def _strip(landed: list[Candidate]) -> list[tuple[float, float]]:
    return [(c.landing_lon, c.landing_lat) for c in landed]


def _title(plan: ReleasePlan) -> str:
    return "DRS release window" + (f" ({DEMO_LABEL})" if plan.is_demo else "")


def to_geojson(plan: ReleasePlan) -> dict[str, Any]:
    about = geojson.Provenance(_title(plan), plan.weather_source, plan.is_demo)
    features = [geojson.feature(geojson.line(_balloon_path(plan)), "balloon path", about)]
    landed = _landed(plan)
    if len(landed) >= 2:
        features.append(geojson.feature(geojson.line(_strip(landed)), "landing strip", about))
    for c in landed:
        features.append(
            geojson.feature(
                geojson.point((c.landing_lon, c.landing_lat)), "candidate landing", about,
                release_time=iso_z(c.release_time), go=c.go, reasons=list(c.reasons),
                zone_probability=c.zone_probability, expected_target_km=c.expected_target_km,
                sigma_major_km=c.sigma_major_km,
            )
        )  # fmt: skip
    best = _recommended(plan)
    if best is not None and best.ellipse is not None:
        for contour in best.ellipse.contours:
            ring = geojson.polygon(best.ellipse.outline(contour))
            features.append(
                geojson.feature(ring, "recommended ellipse", about, release_time=iso_z(best.release_time),
                                probability=contour.probability, n_sigma=contour.n_sigma)
            )  # fmt: skip
    return geojson.collection(features, about, verdict=plan.verdict, warnings=list(plan.warnings))


def to_kml(plan: ReleasePlan) -> str:
    styles = [
        kml.style("balloon", BALLOON_COLOUR, width=1),
        kml.style("strip", STRIP_COLOUR, width=3),
        kml.style("go", GO_COLOUR, width=1, icon_scale=0.6),
        kml.style("no-go", NO_GO_COLOUR, icon_scale=0.6),
    ]
    contents: list[kml.Feature] = [kml.line("balloon path", line_parts(_balloon_path(plan)), "balloon")]
    landed = _landed(plan)
    if len(landed) >= 2:
        contents.append(kml.line("landing strip", line_parts(_strip(landed)), "strip"))
    candidates = [
        kml.point(iso_z(c.release_time)[11:16], position((c.landing_lon, c.landing_lat)),
                  "go" if c.go else "no-go", "GO" if c.go else "NO-GO: " + "; ".join(c.reasons))
        for c in landed
    ]  # fmt: skip
    contents.append(kml.folder("candidates", candidates))
    best = _recommended(plan)
    if best is not None and best.ellipse is not None:
        for contour in best.ellipse.contours:
            name = f"recommended {iso_z(best.release_time)}: {100 * contour.probability:.1f} % ellipse"
            contents.append(kml.polygon(name, polygon_parts(best.ellipse.outline(contour)), "go"))
    description = "\n".join([plan.verdict, f"Weather: {plan.weather_source}", *plan.warnings])
    return kml.document(_title(plan), description, styles, contents)


def write_geojson(plan: ReleasePlan, path: str | Path) -> Path:
    return write_text(path, geojson.dumps(to_geojson(plan)), "GeoJSON")


def write_kml(plan: ReleasePlan, path: str | Path) -> Path:
    return write_text(path, to_kml(plan), "KML")
