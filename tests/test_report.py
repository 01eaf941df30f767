"""Plots and the offline HTML report on a synthetic result with known contents."""

import re

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from flightrecon.events import Event, events_table
from flightrecon.report import make_figures, write_report
from flightrecon.report.html import opening_paragraph
from flightrecon.report.plots import FIGURES, correction_rows, wind_from_speed

EPOCH = "2026-01-01T10:00:00Z"


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def synthetic_result():
    t = np.arange(0, 600, 1.0)
    n = 80 * t
    e = 1000 * np.sin(t / 100)
    lat = 40.0 + n / 111_000.0
    lon = 50.0 + e / (111_000.0 * np.cos(np.radians(40.0)))
    df = pd.DataFrame({"t_s": t, "north_m": n, "east_m": e, "up_m": 3 * t,
                       "north_sd_m": 5 + 0 * t, "east_sd_m": 7 + 0 * t, "up_sd_m": 4 + 0 * t,
                       "lat_deg": lat, "lon_deg": lon, "alt_m": 3 * t - 22.0,
                       "vn_mps": 80 + 0 * t, "ve_mps": 10 * np.cos(t / 100), "vu_mps": 3 + 0 * t,
                       "vn_sd_mps": 0.5 + 0 * t, "ve_sd_mps": 0.5 + 0 * t,
                       "wind_n_mps": -5 + 0 * t, "wind_e_mps": 0 * t,
                       "wind_n_sd_mps": 1 + 0 * t, "wind_e_sd_mps": 1 + 0 * t,
                       "source": pd.array(["joint"] * 300 + ["sns"] * 300, dtype="string"),
                       "sns_north_m": n + 2, "sns_east_m": e - 1, "sns_north_sd_m": 5 + 0 * t,
                       "sabziev_north_m": n + 40, "sabziev_east_m": e + 10,
                       "sabziev_up_m": 3 * t + 5,
                       "arms_dvn_mps": np.cos(t / 50), "arms_dve_mps": np.sin(t / 50),
                       "arms_dvn_sd_mps": 0.5 + 0 * t, "arms_dve_sd_mps": 0.5 + 0 * t,
                       "up_source": pd.array(["joint"] * len(t), dtype="string")})
    grid = pd.DataFrame({"t_s": t, "roll_deg": 20 * np.sin(t / 60), "pitch_deg": 2 + 0 * t,
                         "heading_deg": np.mod(t, 360.0), "n_long_g": 0.01 + 0 * t,
                         "n_lat_g": 0 * t, "n_norm_g": 1 + 0.1 * np.sin(t), "tas_mps": 85 + 0 * t,
                         "baro_alt_m": 3 * t + 10})
    events = [Event("liftoff", 20.0, "lift-off", "lift-off"),
              Event("exceedance", 100.0, "bank +50 deg", "bank beyond 45 deg", end_t_s=110.0,
                    severity="alert"),
              Event("source_change", 300.0, "horizontal position: joint -> sns", "change",
                    severity="caution"),
              Event("touchdown", 580.0, "touchdown", "touchdown")]
    summary = {"flight": {"aircraft_id": "A1", "flight_id": "F1", "epoch_utc": EPOCH,
                          "geoid_undulation_m": -22.0,
                          "departure": {"lat_deg": 40.0, "lon_deg": 50.0, "elev_m": 3.0,
                                        "runway_true_deg": 0.0, "threshold_lat_deg": 40.0,
                                        "threshold_lon_deg": 50.0},
                          "station": {"lat_deg": 40.1, "lon_deg": 50.02, "elev_m": 0.0}},
               "software": {"version": "t"},
               "inputs": [{"path": "x.parquet", "sha256": "ab"}],
               "measurements": {"gnss_fixes": 600, "radar_plots": 0},
               "methods": {"joint": {"status": "ok", "converged": True,
                                     "corrections": {"tas_scale": {"value": 0.02, "sd": 0.002,
                                                                   "unit": "ratio"}}},
                           "sabziev": {"status": "ok", "k1": -0.01,
                                       "history": {"x": [[-0.1, 50.0], [-0.01, 0.2]],
                                                   "y": [[-1e-4, 30.0], [-2e-4, 0.01]]}},
                           "sns": {"status": "ok", "mean_nis": 3.9,
                                   "corrections": {"heading_corr_deg": 0.5,
                                                   "heading_corr_sd_deg": 0.05}},
                           "arms": {"status": "skipped", "reason": "no radar plots"}},
               "events": events_table(events, EPOCH),
               "warnings": ["sabziev: wind unmodelled: no wind channel"]}
    return df, summary, grid


def test_every_figure_drawn_for_a_full_result():
    df, summary, grid = synthetic_result()
    figs = make_figures(df, summary, grid=grid)
    assert set(figs) == set(FIGURES)


def test_recorder_figures_need_the_recorder_channels():
    df, summary, _ = synthetic_result()
    figs = make_figures(df, summary)
    assert "attitude" not in figs and "load_factors" not in figs
    assert {"ground_track", "altitude_profile", "speeds", "wind"} <= set(figs)


def test_time_axes_are_utc_and_altitude_is_msl():
    df, summary, grid = synthetic_result()
    figs = make_figures(df, summary, grid=grid)
    ax = figs["altitude_profile"].axes[0]
    assert "UTC" in ax.get_xlabel()
    line = next(ln for ln in ax.get_lines() if ln.get_label() == "reconstructed altitude, MSL")
    # ellipsoidal height 3 t - 22 minus the undulation -22 m: 3 t above MSL
    np.testing.assert_allclose(line.get_ydata()[:5], 3 * df["t_s"].to_numpy()[:5])
    # feet on the right-hand axis
    assert any("ft" in a.get_ylabel() for a in ax.child_axes)


def test_wind_direction_is_where_it_blows_from():
    # air moving south (wind_n = -5) comes from the north: 0 deg; moving east: from 270
    d, s = wind_from_speed(np.array([-5.0, 0.0]), np.array([0.0, 3.0]))
    np.testing.assert_allclose(d, [0.0, 270.0], atol=1e-9)
    np.testing.assert_allclose(s, [5.0, 3.0])


def test_corrections_readable_with_units_and_truth():
    _, summary, _ = synthetic_result()
    rows = correction_rows(summary, {"aircraft": {"airspeed_scale": 0.021}})
    tas = next(r for r in rows if r["key"] == "tas_scale")
    assert tas["name"] == "Airspeed scale error" and tas["unit"] == "%"
    assert tas["value"] == pytest.approx(2.0) and tas["two_sigma"] == pytest.approx(0.4)
    assert tas["truth"] == pytest.approx(2.1)
    hc = next(r for r in rows if r["key"] == "heading_corr_deg")
    assert hc["unit"] == "deg" and hc["two_sigma"] == pytest.approx(0.1)


def test_opening_paragraph_names_the_method_and_the_share():
    df, summary, _ = synthetic_result()
    text = opening_paragraph(df, summary)
    assert "joint smoother" in text and "50.0 %" in text and "one warning" in text
    summary["methods"]["joint"]["status"] = "unhealthy"
    summary["methods"]["joint"]["health"] = {"problems": [{"what": "did not converge"}]}
    text = opening_paragraph(df, summary)
    assert "is unhealthy (did not converge)" in text and "first <i>healthy</i>" in text


def test_report_is_self_contained_with_every_section(tmp_path):
    df, summary, grid = synthetic_result()
    page = write_report(tmp_path / "rep", df, summary, grid=grid)
    text = page.read_text()
    imgs = re.findall(r'<img [^>]*src="([^"]+)"', text)
    assert len(imgs) == len(FIGURES)
    assert all(s.startswith("data:image/png;base64,") for s in imgs)
    for name in FIGURES:
        assert f'id="fig-{name}"' in text
        assert (tmp_path / "rep" / f"{name}.png").is_file()
    # nothing outside itself: no http(s) URLs, no src/href to files
    assert not re.search(r'(src|href)="(?!data:)', text)
    assert "http://" not in text and "https://" not in text
    for section in ("events", "methods", "corrections", "warnings", "inputs", "flight"):
        assert f'<h2 id="{section}">' in text
    # the events table in UTC, the methods table readable (no JSON dump)
    assert "2026-01-01 10:01:40.0" in text and "bank beyond 45 deg" in text
    assert "<td>skipped</td>" in text and '{"' not in text
    assert "Airspeed scale error" in text


def test_long_results_are_thinned_for_drawing_only():
    from flightrecon.report.plots import ReportContext

    df, summary, grid = synthetic_result()
    long = pd.concat([df] * 200, ignore_index=True)
    long["t_s"] = np.arange(len(long)) * 0.0625
    ctx = ReportContext(long, summary, grid=grid)
    assert len(ctx.track) <= ctx.max_track_rows + 1  # every k-th sample and the last
    assert ctx.track["t_s"].iloc[-1] == long["t_s"].iloc[-1]
    assert ctx.grid is grid  # the recorder channels in full


def test_map_draws_the_known_positions_with_their_2sd_circles():
    """Each --fix (summary: flight.fixes) on the map: a marker at its latitude/longitude, a
    dashed circle of radius 2 sd (to scale: 2 sd in metres north, in degrees of latitude) where
    an sd is given, a label with its UTC time and one legend entry; none without fixes."""
    from matplotlib.patches import Ellipse

    from flightrecon.report.plots import ground_track
    from flightrecon.report.plots.context import ReportContext

    df, summary, grid = synthetic_result()
    fig = ground_track(ReportContext(df, summary, grid=grid))
    ax = fig.axes[0]
    assert not [ln for ln in ax.get_lines() if ln.get_gid() == "known_position"]
    assert not any("known position" in t.get_text() for t in ax.get_legend().get_texts())
    fixes = [{"t_s": 120.0, "lat_deg": 40.09, "lon_deg": 50.004, "alt_msl_m": None, "sd_m": 50.0},
             {"t_s": 400.0, "lat_deg": 40.29, "lon_deg": 50.0, "alt_msl_m": 900.0,
              "sd_m": 200.0},
             {"t_s": 500.0, "lat_deg": 40.36, "lon_deg": 49.99, "sd_m": None}]
    summary["flight"]["fixes"] = fixes
    fig = ground_track(ReportContext(df, summary, grid=grid))
    ax = fig.axes[0]
    marks = [ln for ln in ax.get_lines() if ln.get_gid() == "known_position"]
    assert [(float(m.get_ydata()[0]), float(m.get_xdata()[0])) for m in marks] == \
        [(f["lat_deg"], f["lon_deg"]) for f in fixes]
    circles = [p for p in ax.patches if isinstance(p, Ellipse)
               and p.get_gid() == "known_position_2sd"]
    assert len(circles) == 2        # the third fix has no sd
    for c, f in zip(circles, fixes[:2]):
        assert c.center == (f["lon_deg"], f["lat_deg"])
        assert c.height / 2 == pytest.approx(2 * f["sd_m"] / 110540.0, rel=1e-12)
    labels = [t.get_text() for t in ax.texts if t.get_text().startswith("fix ")]
    assert labels == ["fix 10:02:00 UTC", "fix 10:06:40 UTC", "fix 10:08:20 UTC"]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert sum("known positions (--fix, 3)" in t for t in legend) == 1
