"""Every KML the project writes validates against the OGC KML 2.2 schema and never jumps across ±180°."""

from __future__ import annotations

from pathlib import Path

import fastkml
import pytest
from lxml import etree

from tests.predictor.geofiles.exports.conftest import PRODUCTS, Written

KML = "{http://www.opengis.net/kml/2.2}"
SCHEMA = Path(fastkml.__file__).parent / "schema" / "ogckml22.xsd"


@pytest.fixture(scope="module")
def schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA)))


@pytest.mark.parametrize("product", PRODUCTS)
def test_every_kml_validates_against_the_ogc_kml_22_schema(
    products: dict[str, Written], schema: etree.XMLSchema, product: str
) -> None:
    document = etree.fromstring(products[product].kml.encode("utf-8"))
    assert schema.validate(document), "\n".join(str(e) for e in schema.error_log)


@pytest.mark.parametrize("product", PRODUCTS)
def test_kml_lines_and_rings_are_cut_at_the_antimeridian_not_drawn_round_the_globe(
    products: dict[str, Written], product: str
) -> None:
    written = products[product]
    document = etree.fromstring(written.kml.encode("utf-8"))
    lines = [e.text.split() for e in document.iter(f"{KML}coordinates") if len(e.text.split()) > 1]
    assert lines, "the document draws no line or ring"
    edges = set()
    for line in lines:
        lons = [float(point.split(",")[0]) for point in line]
        assert all(-180.0 <= lon <= 180.0 for lon in lons)
        assert max(abs(b - a) for a, b in zip(lons, lons[1:], strict=False)) < 5.0
        edges |= {lon for lon in lons if abs(lon) == 180.0}
    assert (edges == {-180.0, 180.0}) == written.crosses_antimeridian


@pytest.mark.parametrize("product", [p for p in PRODUCTS if "DEMO" in p])
def test_a_demo_kml_names_itself_demo(products: dict[str, Written], product: str) -> None:
    document = etree.fromstring(products[product].kml.encode("utf-8"))
    assert "DEMO WEATHER" in document.findtext(f"{KML}Document/{KML}name")
