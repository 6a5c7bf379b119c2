"""KML documents that validate against the OGC KML 2.2 schema (ogckml22.xsd).

Written with fastkml 1.x rather than by hand or with simplekml: fastkml models the schema's element
order (a Document's name before its styles, altitudeMode before coordinates) and writes ids only
where given: simplekml got all three wrong, and every file failed the schema.
"""

from __future__ import annotations

from collections.abc import Sequence

from fastkml import containers, features, geometry, kml, styles
from fastkml.enums import AltitudeMode
from pygeoif import geometry as geo

from predictor.geofiles.geometry import Coordinate

Feature = features.Placemark | containers.Folder


def style(
    style_id: str, colour: str, width: float | None = None, icon_scale: float | None = None
) -> styles.Style:
    """A shared style: lines (and unfilled polygon outlines) of ``colour``, or icons tinted with it.

    KML colours are aabbggrr.
    """
    parts: list[styles.LineStyle | styles.PolyStyle | styles.IconStyle] = []
    if width is not None:
        parts += [styles.LineStyle(color=colour, width=width), styles.PolyStyle(fill=False)]
    if icon_scale is not None:
        parts.append(styles.IconStyle(color=colour, scale=icon_scale))
    return styles.Style(id=style_id, styles=parts)


def _placemark(
    name: str | None, shape: geometry.KMLGeometryType, style_id: str | None, description: str | None
) -> features.Placemark:
    return features.Placemark(
        name=name,
        description=description,
        style_url=styles.StyleUrl(url=f"#{style_id}") if style_id else None,
        kml_geometry=shape,
    )


def _mode(absolute: bool) -> AltitudeMode | None:
    return AltitudeMode.absolute if absolute else None


def _one_or_many(shapes: list[geometry.KMLGeometryType]) -> geometry.KMLGeometryType:
    return shapes[0] if len(shapes) == 1 else geometry.MultiGeometry(kml_geometries=shapes)


def line(
    name: str,
    parts: Sequence[Sequence[Coordinate]],
    style_id: str | None = None,
    description: str | None = None,
    absolute: bool = False,
) -> features.Placemark:
    """A path from geometry.line_parts: one LineString, or several when it crosses ±180°."""
    shapes: list[geometry.KMLGeometryType] = [
        geometry.LineString(geometry=geo.LineString(_points(part)), altitude_mode=_mode(absolute))
        for part in parts
    ]
    return _placemark(name, _one_or_many(shapes), style_id, description)


def polygon(
    name: str,
    parts: Sequence[Sequence[Coordinate]],
    style_id: str | None = None,
    description: str | None = None,
) -> features.Placemark:
    """A ring from geometry.polygon_parts: one Polygon, or several when it crosses ±180°."""
    shapes: list[geometry.KMLGeometryType] = [
        geometry.Polygon(geometry=geo.Polygon(_points(part))) for part in parts
    ]
    return _placemark(name, _one_or_many(shapes), style_id, description)


def _points(part: Sequence[Coordinate]) -> list[tuple[float, float]] | list[tuple[float, float, float]]:
    """The points as pygeoif takes them: all (lon, lat), or all (lon, lat, altitude), as a part's are."""
    if all(len(c) == 2 for c in part):
        return [(c[0], c[1]) for c in part]
    return [(c[0], c[1], c[2]) for c in part]


def point(
    name: str | None,
    where: Coordinate,
    style_id: str | None = None,
    description: str | None = None,
    absolute: bool = False,
) -> features.Placemark:
    """A point from geometry.position; ``absolute`` places it at its altitude instead of on the ground."""
    return _placemark(
        name, geometry.Point(geometry=geo.Point(*where), altitude_mode=_mode(absolute)), style_id, description
    )


def folder(name: str, contents: Sequence[Feature]) -> containers.Folder:
    return containers.Folder(name=name, features=list(contents))


def document(name: str, description: str, shared: Sequence[styles.Style], contents: Sequence[Feature]) -> str:
    doc = containers.Document(
        name=name, description=description, styles=list(shared), features=list(contents)
    )
    body = kml.KML(features=[doc]).to_string(prettyprint=True)
    return f'<?xml version="1.0" encoding="UTF-8"?>\n{body}'
