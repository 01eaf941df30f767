"""Plots and the offline HTML report on a synthetic result table."""

import re

import numpy as np
import pandas as pd

from flightrecon.report import make_figures, write_report


def synthetic_result():
    t = np.arange(0, 600, 1.0)
    n = 80 * t
    e = 1000 * np.sin(t / 100)
    df = pd.DataFrame({"t_s": t, "north_m": n, "east_m": e, "up_m": 3 * t,
                       "north_sd_m": 5 + 0 * t, "east_sd_m": 7 + 0 * t,
                       "sns_north_m": n + 2, "sns_east_m": e - 1, "sns_north_sd_m": 5 + 0 * t,
                       "sabziev_north_m": n + 40, "sabziev_east_m": e + 10,
                       "sabziev_up_m": 3 * t + 5,
                       "arms_dvn_mps": np.cos(t / 50), "arms_dve_mps": np.sin(t / 50),
                       "arms_dvn_sd_mps": 0.5 + 0 * t, "arms_dve_sd_mps": 0.5 + 0 * t,
                       "up_source": pd.array(["sabziev"] * len(t), dtype="string")})
    summary = {"flight": {"aircraft_id": "A1", "flight_id": "F1"}, "software": {"version": "t"},
               "inputs": [{"path": "x.parquet", "sha256": "ab"}],
               "methods": {"sabziev": {"status": "ok", "k1": -0.01,
                                       "history": {"x": [[-0.1, 50.0], [-0.01, 0.2]],
                                                   "y": [[-1e-4, 30.0], [-2e-4, 0.01]]}},
                           "sns": {"status": "ok", "mean_nis": 3.9,
                                   "corrections": {"heading_deg": {"value": 0.5, "sd": 0.05}}}},
               "warnings": ["wind unmodelled"]}
    return df, summary


def test_figures_drawn_for_available_data():
    df, summary = synthetic_result()
    figs = make_figures(df, summary)
    assert {"ground_track", "altitude_profile", "method_differences", "air_data_error",
            "sensor_corrections", "innovations", "newton_history"} <= set(figs)


def test_report_is_self_contained(tmp_path):
    df, summary = synthetic_result()
    page = write_report(tmp_path / "rep", df, summary)
    text = page.read_text()
    imgs = re.findall(r'<img [^>]*src="([^"]+)"', text)
    assert len(imgs) >= 5 and all(s.startswith("data:image/png;base64,") for s in imgs)
    # nothing outside itself: no http(s) URLs, no src/href to files
    assert not re.search(r'(src|href)="(?!data:)', text)
    assert "http://" not in text and "https://" not in text
    assert (tmp_path / "rep" / "ground_track.png").is_file()
