"""Values that parse but were probably not meant: one warning line each, never a refusal."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import shapely

from console.commands.main import main
from predictor.prediction.plausibility import far_features_warning, far_team_warning, release_altitude_warning
from tests.console.commands.test_cli_plan import args as plan_args, geojson_file, grib_files  # noqa: F401  (the fixture)


@pytest.mark.parametrize(("alt", "warned"), [(31.5, True), (1.0, True), (59.9, True), (0.0, False),
                                             (400.0, False), (28000.0, False)])  # fmt: skip
def test_an_altitude_that_looks_like_kilometres_is_named(alt: float, warned: bool) -> None:
    warning = release_altitude_warning(alt)
    assert (warning is not None) is warned
    if warned:
        assert f"did you mean {alt:g} km (--alt {alt * 1000:.0f})?" in (warning or "")


def test_zones_far_from_the_release_are_named_and_a_swap_is_suggested() -> None:
    lake = shapely.box(9.0, 45.0, 9.5, 47.0)  # near 46 N 6 E, in GeoJSON's (lon, lat)
    swapped = shapely.box(45.0, 9.0, 47.0, 9.5)
    assert far_features_warning("exclusion zone", [lake], [(46.0, 6.0)]) is None
    warning = far_features_warning("exclusion zone", [swapped], [(46.0, 6.0)])
    assert warning is not None and warning.startswith("every exclusion zone is over ")
    assert "with longitude and latitude swapped the nearest is " in warning
    elsewhere = far_features_warning("target", [shapely.Point(140.0, -35.0)], [(46.0, 6.0)])
    assert elsewhere is not None and "is it the file for this flight?" in elsewhere


def test_a_team_far_from_the_capsule_is_warned_and_a_swap_suggested() -> None:
    assert far_team_warning((46.49, 6.60), (46.50, 6.60)) is None
    warning = far_team_warning((6.60, 46.49), (46.50, 6.60))
    assert warning is not None and "as LON,LAT it would be 1 km away" in warning
    assert "LON,LAT" not in (far_team_warning((-33.9, 151.2), (46.5, 6.6)) or "")


def test_drs_predict_warns_of_an_altitude_typed_in_km(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["predict", "--demo-weather", "--lat", "46.5", "--lon", "6.6", "--alt", "31.5",
            "--time", "2026-11-22T12:00Z", "--cache-dir", str(tmp_path), "--json"]  # fmt: skip
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "drs: warning: --alt 31.5 m is a release 31.5 metres up; did you mean 31.5 km" in captured.err
    assert json.loads(captured.out)["release"]["alt_m"] == 31.5  # warned, not changed


def test_drs_plan_warns_of_a_zones_file_with_swapped_coordinates(
    grib_files: list[Path],  # noqa: F811
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    swapped = geojson_file(
        tmp_path / "z.geojson",
        {"type": "Polygon", "coordinates": [[[45, 9], [45, 9.5], [47, 9.5], [47, 9], [45, 9]]]},
        "lake",
    )
    assert main(plan_args(grib_files, tmp_path, "--zones", str(swapped))) == 0
    err = capsys.readouterr().err
    assert "drs: warning: every exclusion zone is over " in err and "swapped" in err
