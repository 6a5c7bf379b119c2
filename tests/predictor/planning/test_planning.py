"""The release-window sweep: same answers as single predictions, windows, no-go, coverage, balloon path."""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
import shapely

from predictor.descent import Release
from predictor.environment.cube import WeatherCube
from predictor.errors import PredictorError
from predictor.planning import Criteria, Sweep
from predictor.planning.balloon import AltitudePlan, balloon_path
from predictor.planning.strip import to_geojson, to_kml, write_geojson, write_kml
from predictor.planning.sweep import Candidate, Thresholds, plan_release, rank_windows
from predictor.prediction import EnsembleSpread, FlightSetup
from predictor.prediction.landings import predict, predict_ensemble
from predictor.prediction.zones import Feature, load_zones
from tests.predictor.predict_helpers import RELEASE, isothermal_cube


def sheared_cube(is_demo: bool = False, hours: tuple[float, ...] = (-6.0, 18.0)) -> WeatherCube:
    """Wind that changes with altitude, position and time, so nothing can agree by accident."""
    return isothermal_cube(
        u=lambda t, z, y, x: 8.0 + z / 2000.0 + 0.5 * (x - 6.0) + 0.2 * t,
        v=lambda t, z, y, x: 2.0 + 0.8 * (y - 46.0) - z / 10000.0,
        hours=hours,
        is_demo=is_demo,
    )


def test_sweep_landings_equal_single_predictions_with_the_same_drift() -> None:
    cube = sheared_cube()
    plan = plan_release(cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(1.0, 10.0))
    assert len(plan.candidates) == 7
    for c in plan.candidates:
        single = predict(cube, Release(RELEASE, 46.0, 6.0, 30000.0, drift_minutes=10.0 * c.index))
        assert c.release_time == single.release.time
        assert c.release_lat == pytest.approx(single.release.lat, abs=1e-10)
        assert c.landing_lat == pytest.approx(single.landing.lat, abs=1e-10)
        assert c.landing_lon == pytest.approx(single.landing.lon, abs=1e-10)
        assert c.landing_time == single.landing.time
        assert c.drift_km == pytest.approx(single.drift_km, rel=1e-9)
        assert c.t_future_mean_h == pytest.approx(single.t_future_mean_h, rel=1e-9)
        assert c.ellipse is not None
        assert c.ellipse.sigma_parallel_km == pytest.approx(single.ellipse.sigma_parallel_km, rel=1e-9)
    # The balloon really moved between candidates, so the landings differ.
    assert plan.candidates[-1].landing_lon - plan.candidates[0].landing_lon > 0.1


def test_first_candidate_members_equal_predict_ensemble_with_the_same_seed() -> None:
    cube = sheared_cube()
    plan = plan_release(
        cube,
        Release(RELEASE, 46.0, 6.0, 30000.0),
        Sweep(0.5, 15.0, member_step_m=100.0),
        spread=EnsembleSpread(members=40, seed=7),
    )
    ensemble = predict_ensemble(
        cube, Release(RELEASE, 46.0, 6.0, 30000.0), spread=EnsembleSpread(members=40, seed=7)
    )
    first = plan.candidates[0]
    assert first.member_lat is not None and first.member_lon is not None
    np.testing.assert_allclose(first.member_lat, ensemble.member_lat, atol=1e-10)
    np.testing.assert_allclose(first.member_lon, ensemble.member_lon, atol=1e-10)
    assert first.uncertainty.startswith("ensemble (40 members)")
    # Later candidates add the balloon's own drift error: their spread is wider.
    assert plan.candidates[-1].sigma_major_km > first.sigma_major_km + 0.5


def test_every_candidate_no_go_is_reported_as_an_empty_window() -> None:
    cube = sheared_cube()
    everywhere = Feature("sea", shapely.box(0.0, 40.0, 13.0, 53.0))
    plan = plan_release(
        cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(1.0, 20.0), criteria=Criteria(zones=[everywhere])
    )
    assert plan.windows == ()
    assert plan.go_count == 0
    assert plan.verdict.startswith("NO-GO: none of the 4 candidate release times")
    doc = plan.to_dict()
    assert doc["windows"] == [] and doc["go_candidates"] == 0
    assert all(c["reasons"] and "P(zone) 1.000" in c["reasons"][0] for c in doc["candidates"])


def test_windows_are_runs_of_go_candidates_and_the_best_is_recommended() -> None:
    cube = sheared_cube()
    free = plan_release(cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(2.0, 10.0))
    lons = [c.landing_lon for c in free.candidates]
    # A town over the landings of the middle of the sweep splits it into two windows.
    mid = free.candidates[6]
    town = Feature("town", shapely.Point(mid.landing_lon, mid.landing_lat).buffer(0.25))
    road = Feature("road", shapely.LineString([(lons[10], 40.0), (lons[10], 53.0)]))
    plan = plan_release(
        cube,
        Release(RELEASE, 46.0, 6.0, 30000.0),
        Sweep(2.0, 10.0),
        criteria=Criteria(zones=[town], targets=[road]),
    )
    go = [c.go for c in plan.candidates]
    assert not go[6] and go[0] and go[-1]
    windows = plan.windows
    assert len(windows) == 2
    for w in windows:
        assert all(go[w.first : w.last + 1])
        assert w.first == 0 or not go[w.first - 1]
        assert w.last == len(go) - 1 or not go[w.last + 1]
    best = windows[0]
    # Ranked by expected distance from the road: the window that contains the road's candidate wins.
    assert best.first <= 10 <= best.last
    scores = [plan.candidates[i].expected_target_km for i in range(best.first, best.last + 1)]
    assert plan.candidates[best.recommended].expected_target_km == min(scores)  # type: ignore[type-var]
    assert plan.verdict.startswith("GO:")


def test_thresholds_on_target_distance_and_sigma_make_candidates_no_go() -> None:
    cube = sheared_cube()
    far = Feature("recovery point", shapely.Point(12.5, 52.5))
    plan = plan_release(
        cube,
        Release(RELEASE, 46.0, 6.0, 30000.0),
        Sweep(0.5, 10.0),
        criteria=Criteria(
            targets=[far],
            thresholds=Thresholds(max_zone_probability=0.05, max_target_km=50.0, max_sigma_km=0.5),
        ),
    )  # fmt: skip
    for c in plan.candidates:
        assert not c.go
        assert any("expected target distance" in r for r in c.reasons)
        assert any("1σ" in r for r in c.reasons)
        assert c.expected_target_km is not None and c.expected_target_km > 300.0


def test_candidates_beyond_the_weather_are_no_go_and_the_rest_still_plan() -> None:
    cube = sheared_cube(hours=(-6.0, 2.0))
    plan = plan_release(
        cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(3.0, 30.0), FlightSetup(time_tolerance_s=0.0)
    )
    statuses = [c.status for c in plan.candidates]
    assert statuses[0] is None and statuses[1] is None
    assert statuses[-1] is not None and not plan.candidates[-1].go
    assert "beyond" in (statuses[-1] or "") or "left the weather" in (statuses[-1] or "")
    assert plan.candidates[-1].to_dict()["status"] == statuses[-1]


def test_balloon_follows_the_wind_at_the_planned_altitude_and_its_sigma_grows() -> None:
    cube = isothermal_cube(u=lambda t, z, y, x: z / 1000.0, v=0.0)
    at_float = balloon_path(cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(1.0, 30.0))
    plan = AltitudePlan((RELEASE,), (20000.0,))
    planned = balloon_path(cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(1.0, 30.0, altitude_plan=plan))
    km_per_deg = 111.32 * math.cos(math.radians(46.0))
    assert (at_float.lon[-1] - 6.0) * km_per_deg == pytest.approx(30.0 * 3.6, rel=0.01)
    assert (planned.lon[-1] - 6.0) * km_per_deg == pytest.approx(20.0 * 3.6, rel=0.01)
    assert planned.alt_m[-1] == 20000.0
    assert at_float.sigma_km[0] < 0.02
    assert at_float.sigma_km[-1] == pytest.approx(2.0 * 3.6, rel=1e-3)


def test_altitude_plan_text_is_parsed_and_bad_plans_are_refused() -> None:
    plan = AltitudePlan.parse("2024-05-01T06:00Z=30000, 2024-05-01T07:00Z=28000")
    assert float(plan.altitude_at((RELEASE + timedelta(minutes=30)).timestamp())) == pytest.approx(29000.0)
    for text, message in (
        ("2024-05-01T06:00Z", "TIME=METRES"),
        ("2024-05-01T06:00=3000", "needs a zone"),
        ("2024-05-01T07:00Z=3000,2024-05-01T06:00Z=3000", "strictly increasing"),
        ("2024-05-01T06:00Z=-5", "positive"),
    ):
        with pytest.raises(PredictorError, match=message):
            AltitudePlan.parse(text)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"hours": -1.0}, "sweep length"),
        ({"every_minutes": 0.0}, "sweep step"),
        ({"members": 2}, "at least 3 members"),
        (
            {"members": 10_000_000},
            r"7 candidates × 10000000 members is 70,000,000 member descents, over the 2,000,000",
        ),
        ({"thresholds": Thresholds(max_target_km=10.0)}, "needs a targets file"),
        ({"time": RELEASE.replace(tzinfo=None)}, "timezone-aware"),
        ({"alt_m": -3.0}, "positive number of metres"),
        ({"member_step_m": 0.0, "members": 5}, "member altitude step"),
        ({"lat": 60.0}, "outside the weather region"),
        ({"time": RELEASE + timedelta(days=2)}, "but the weather covers"),
        ({"drift_minutes": 10.0}, "a sweep starts where the balloon is now"),
    ],
)
def test_bad_sweep_questions_are_refused_with_a_specific_message(kwargs: dict, message: str) -> None:
    args = {"time": RELEASE, "lat": 46.0, "lon": 6.0, "alt_m": 30000.0, "hours": 1.0, "every_minutes": 10.0}
    args.update(kwargs)
    sweep = Sweep(args.pop("hours"), args.pop("every_minutes"), member_step_m=args.pop("member_step_m", None))
    spread = EnsembleSpread(args.pop("members")) if "members" in args else None
    criteria = Criteria(thresholds=args.pop("thresholds", Thresholds()))
    with pytest.raises(PredictorError, match=message):
        plan_release(sheared_cube(), Release(**args), sweep, spread=spread, criteria=criteria)


def test_bad_thresholds_are_refused() -> None:
    with pytest.raises(PredictorError, match="max zone probability"):
        Thresholds(max_zone_probability=1.5)
    with pytest.raises(PredictorError, match="max sigma km"):
        Thresholds(max_sigma_km=-1.0)


def test_landing_strip_files_carry_every_candidate_and_say_demo(tmp_path: Path) -> None:
    plan = plan_release(sheared_cube(is_demo=True), Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(1.0, 15.0))
    doc = to_geojson(plan)
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds.count("candidate landing") == len(plan.candidates) == 5
    strip = next(f for f in doc["features"] if f["properties"]["kind"] == "landing strip")
    assert strip["geometry"]["coordinates"][0] == pytest.approx(
        [plan.candidates[0].landing_lon, plan.candidates[0].landing_lat], abs=5e-7
    )
    assert kinds.count("recommended ellipse") == 3
    assert doc["drs"]["is_demo"] and "DEMO" in doc["drs"]["title"]
    assert all(f["properties"]["is_demo"] and "DEMO" in f["properties"]["title"] for f in doc["features"])
    assert "DEMO WEATHER" in to_kml(plan)
    gj = write_geojson(plan, tmp_path / "strip.geojson")
    assert json.loads(gj.read_text())["type"] == "FeatureCollection"
    kml = write_kml(plan, tmp_path / "strip.kml")
    assert "landing strip" in kml.read_text()
    with pytest.raises(PredictorError, match="cannot write the KML"):
        write_kml(plan, tmp_path / "missing-dir" / "x.kml")


def test_a_sweep_across_the_antimeridian_sees_a_zone_written_across_it(tmp_path: Path) -> None:
    cube = isothermal_cube(
        lats=np.arange(-50.0, -39.0, 1.0), lons=np.arange(170.0, 191.0, 1.0), u=12.0, v=0.0
    )
    free = plan_release(cube, Release(RELEASE, -45.0, 179.4, 30000.0), Sweep(1.0, 20.0))
    lons = [c.landing_lon for c in free.candidates]
    assert lons[1] > 179.8 and -180.0 < lons[2] < -179.8, "landings 1 and 2 straddle 180°"
    # A strait from 179.85° E to 179.85° W, written as GeoJSON the short way across the antimeridian.
    ring = [[179.85, -45.2], [-179.85, -45.2], [-179.85, -44.8], [179.85, -44.8], [179.85, -45.2]]
    path = tmp_path / "strait.geojson"
    path.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    plan = plan_release(
        cube,
        Release(RELEASE, -45.0, 179.4, 30000.0),
        Sweep(1.0, 20.0),
        criteria=Criteria(zones=load_zones(path)),
    )
    p = [c.zone_probability for c in plan.candidates]
    # Both landings next to 180° are mostly in the strait; the first (8 km west of it) much less.
    assert p[1] > 0.3 and p[2] > 0.3
    assert p[0] < 0.5 * min(p[1], p[2])
    assert not plan.candidates[1].go and not plan.candidates[2].go


def test_ensemble_zone_probability_agrees_with_counting_its_members() -> None:
    cube = sheared_cube()
    probe = plan_release(cube, Release(RELEASE, 46.0, 6.0, 30000.0), Sweep(0.0, 10.0))
    c = probe.candidates[0]
    # A zone over the eastern half of the landing ellipse.
    zone = Feature("half", shapely.box(c.landing_lon, 40.0, 13.0, 53.0))
    plan = plan_release(
        cube,
        Release(RELEASE, 46.0, 6.0, 30000.0),
        Sweep(0.0, 10.0),
        spread=EnsembleSpread(members=400, seed=2),
        criteria=Criteria(zones=[zone]),
    )
    member = plan.candidates[0]
    assert member.members_in_zones is not None
    assert 0.3 < member.zone_probability < 0.7
    assert member.zone_probability == pytest.approx(member.members_in_zones, abs=0.06)


def test_a_windows_recommendation_weighs_the_ellipse_when_zones_do_not_decide() -> None:
    """No zones: every P(zone) is 0. The middle used to win even where its ellipse was 3× the start's."""
    start = datetime(2024, 5, 1, 1, tzinfo=UTC)
    sigmas = [2.0, 3.0, 6.0, 6.0, 6.0, 4.0]
    candidates = [
        Candidate(i, start + timedelta(minutes=5 * i), 46.0, 6.0, 28000.0, 0.0, None,
                  sigma_major_km=sigma, zone_probability=0.0, go=True)
        for i, sigma in enumerate(sigmas)
    ]  # fmt: skip
    [window] = rank_windows(candidates, by_target=False)
    assert window.recommended == 0
    candidates[0] = Candidate(0, start, 46.0, 6.0, 28000.0, 0.0, None, sigma_major_km=2.0,
                              zone_probability=0.02, go=True)  # fmt: skip
    [window] = rank_windows(candidates, by_target=False)
    assert window.recommended == 1  # a real zone risk outweighs a smaller ellipse
