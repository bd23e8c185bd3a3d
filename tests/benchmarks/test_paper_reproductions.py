"""The paper reproductions of benchmarks/paper_reproductions.py (docs/variants.md section 6): the helpers against
closed forms, and (slow) the orderings the tables report, over a couple of seeds."""

from __future__ import annotations

import math

import pytest

from benchmarks import paper_reproductions as pr


def test_degrees_of_position_match_the_wgs84_radii():
    """Metres per degree from the meridian and prime-vertical radii (closed forms at the equator and the pole)."""
    a, e2 = 6378137.0, 6.69437999014e-3
    m_lat, m_lon = pr.degrees_of_position(0.0, 0.0)
    assert math.isclose(m_lat, a * (1 - e2) * math.pi / 180, rel_tol=1e-12)
    assert math.isclose(m_lon, a * math.pi / 180, rel_tol=1e-12)
    m_lat90, _ = pr.degrees_of_position(90.0, 0.0)
    assert math.isclose(m_lat90, a / math.sqrt(1 - e2) * math.pi / 180, rel_tol=1e-12)
    # Beijing: ~111.0 km per degree of latitude, ~85.4 km per degree of longitude
    lat_m, lon_m = pr.degrees_of_position(39.979, 50.0)
    assert 110.9e3 < lat_m < 111.1e3 and 85.2e3 < lon_m < 85.6e3


def test_seeds_parse_ranges_and_lists():
    assert pr.parse_seeds("1-3,7") == [1, 2, 3, 7]
    assert pr.parse_seeds("4") == [4]


def test_tables_report_the_paper_next_to_the_mean_and_range():
    se = {"lat_mae_deg": 0.05, "lon_mae_deg": 0.01}
    ins = {"lat_mae_deg": 0.10, "lon_mae_deg": 0.40}
    md = pr.zhang_table([{"se": se, "sins": ins, "lat_change": -0.5, "lon_change": -0.975}])
    assert "| latitude change against pure SINS | -50 (-50 .. -50) % | -59.4 % |" in md
    assert "| seeds where both MAE fall | 1 of 1 | |" in md
    assert "| change of the mean MAE over the seeds, latitude / longitude | -50% / -98% | |" in md
    row = {c: {"heading_rms_deg": v, "heading_max_deg": 2 * v} for c, v in
           (("fused", 0.1), ("pol_mimu", 0.2), ("sins_gnss", 1.0))}
    md = pr.ge_table([{**row, "ordered": True}])
    assert "| RMS | 0.100 (0.100 .. 0.100) | 0.200 (0.200 .. 0.200) | 1.000 (1.000 .. 1.000) |" in md
    assert "1 of 1 | 1 of 1 | 1 of 1 |" in md


def test_along_across_the_suns_azimuth_by_closed_forms():
    """An error along the azimuth is all "along"; a quarter turn to the right of it all "across"; the angle off the
    azimuth line ignores the signs."""
    az = math.radians(252.0)
    a, c = pr.along_across(math.sin(az) * 10.0, math.cos(az) * 10.0, az)
    assert math.isclose(a, 10.0) and abs(c) < 1e-12
    a, c = pr.along_across(math.cos(az) * 4.0, -math.sin(az) * 4.0, az)
    assert abs(a) < 1e-12 and math.isclose(c, 4.0)
    assert math.isclose(pr.drift_off_azimuth_deg(-3.0, 3.0), 45.0)
    assert math.isclose(pr.drift_off_azimuth_deg(-5.0, 0.0), 0.0)


def test_zhang_paper_drift_lies_along_the_suns_azimuth():
    """The paper's pure SINS ended (-1.436 deg, -0.568 deg) in (longitude, latitude): 134 km along the Sun's azimuth
    (252-256 deg over the test) and 31 km across it, 13 deg off the azimuth line; its sun-elevation filter's largest
    excursions (-0.035, -0.111 deg) are mostly across (docs/variants.md 6.4)."""
    assert 251.5 < math.degrees(pr.sun_azimuth_rad(0.0)) < 252.5
    assert 255.0 < math.degrees(pr.sun_azimuth_rad(1200.0)) < 256.5
    d = pr.zhang_paper_drift()
    assert 130.0 < d["sins_along_km"] < 138.0 and -34.0 < d["sins_across_km"] < -28.0
    assert 11.0 < d["sins_off_azimuth_deg"] < 15.0
    assert abs(d["se_across_km"]) > abs(d["se_along_km"])


def test_zhang_table_splits_along_and_across_and_picks_the_paper_like_draws():
    def member(seed: int, along: float, across: float, lat_change: float) -> dict:
        se = {"lat_mae_deg": 0.05, "lon_mae_deg": 0.01, "along_mae_km": 1.0, "across_mae_km": 5.0}
        ins = {"lat_mae_deg": 0.10, "lon_mae_deg": 0.40, "along_mae_km": 30.0, "across_mae_km": 6.0,
               "end_along_km": along, "end_across_km": across,
               "end_off_azimuth_deg": pr.drift_off_azimuth_deg(along, across)}
        return {"seed": seed, "se": se, "sins": ins, "lat_change": lat_change, "lon_change": -0.9}

    # seed 1 ends opposite to the paper's drift (the same line), seed 2 as far to the right of the azimuth line as
    # the paper's is to its left (26 deg from it: its across part lies on the other side), seed 3 across the azimuth
    rows = [member(1, -40.0, 9.0, -0.6), member(2, 40.0, 9.0, 1.0), member(3, 1.0, 40.0, 0.5)]
    assert [pr.zhang_paper_like(r) for r in rows] == [True, False, False]
    assert pr.line_separation_deg(pr.drift_line_deg(40.0, 9.0), pr.drift_line_deg(40.0, -9.0)) == \
        pytest.approx(2 * math.degrees(math.atan2(9.0, 40.0)))
    md = pr.zhang_table(rows)
    assert "| pure SINS at 20 min, angle off the Sun's azimuth line (deg) | 38 (13 .. 89) | 13 |" in md
    assert "(1): latitude / longitude change | -60 (-60 .. -60) % / -90 (-90 .. -90) % | -59.4 % / -98.1 % |" in md


@pytest.mark.slow
@pytest.mark.timeout(2400)
def test_zhang_sun_elevation_cuts_the_longitude_error_of_pure_sins():
    """Zhang et al. like for like, seeds 1-2: the sun elevation observes the position along the Sun's azimuth
    (252 deg at 16:14: mostly longitude), so the longitude MAE falls against pure SINS on the same world and seed
    (measured -87 % and -62 %; paper -98 %). Latitude is mostly across the azimuth and not asserted (docs/variants.md
    6.4: -66 % .. +268 % over 10 seeds)."""
    res = pr.zhang([1, 2], log=lambda s: None)
    for m in res["members"]:
        assert m["lon_change"] < -0.4, m
        assert m["sins"]["lon_mae_deg"] > 0.05, m  # the paper's SINS drifts: Table 1's 5 deg/h, no GNSS calibration


@pytest.mark.slow
@pytest.mark.timeout(2400)
def test_ge_federated_under_field_presets_keeps_sins_gnss_worst():
    """Ge et al. under the field presets, seeds 1-2: SINS/GNSS (heading unobservable while static) stays the worst of
    the three configurations on every seed. Fused < pol/MIMU holds on most seeds only (seed 1: 0.372 against
    0.338 deg), so it is reported in docs/variants.md 6.3, not asserted here."""
    res = pr.ge([1, 2], log=lambda s: None)
    for m in res["members"]:
        g = m["sins_gnss"]["heading_rms_deg"]
        assert m["fused"]["heading_rms_deg"] < g and m["pol_mimu"]["heading_rms_deg"] < g, m
        assert m["fused"]["heading_rms_deg"] < 0.5, m
