"""The height from the pressure altitude and its sd (flightrecon/geo/pressure_height.py): the
default result's height where no estimator gives one."""

from __future__ import annotations

import numpy as np
import pytest

from flightrecon.geo.pressure_height import (
    DH_P_DQNH_M,
    MIN_SAT_SAMPLES,
    isa_deviation_k,
    pressure_height_m,
)


def test_worked_numbers():
    """1500 m of pressure altitude above a field at 0, a column 10 K warmer than the ISA:
    1552.96 m (atmosphere.height_above_field_m's worked number); dH/ddT = 5.296 m/K there, so
    with the QNH given at the take-off and the SAT's spread 0 the sd is
    sqrt(8.3^2 + (1.5 x 5.296)^2) = 11.49 m, an hour later sqrt(2 x 8.3^2 + 7.94^2) = 14.18 m;
    without a QNH nor a temperature sqrt(83^2 + (10 x 5.296)^2) = 98.46 m."""
    H, sd = pressure_height_m(np.array([0.0, 3600.0]), np.array([1500.0, 1500.0]), 0.0,
                              qnh_known=True, deviation=(10.0, 0.0), t0_s=0.0)
    assert H[0] == pytest.approx(1552.96, abs=0.01)
    dF = 5.296
    assert sd[0] == pytest.approx(np.hypot(DH_P_DQNH_M, 1.5 * dF), abs=0.01)
    assert sd[1] == pytest.approx(np.sqrt(2 * DH_P_DQNH_M ** 2 + (1.5 * dF) ** 2), abs=0.01)
    H0, sd0 = pressure_height_m(np.array([0.0]), np.array([1500.0]), 0.0, qnh_known=False,
                                deviation=None, t0_s=0.0)
    assert H0[0] == pytest.approx(1500.0) and sd0[0] == pytest.approx(98.46, abs=0.02)


def test_isa_deviation_from_the_airborne_samples():
    """The mean and spread of SAT - T_ISA(h_p) over the airborne samples with a temperature;
    None with too few of them or without a temperature."""
    h = np.full(200, 1000.0)                    # T_ISA(1000 m) = 281.65 K = 8.5 degC
    sat = np.where(np.arange(200) % 2 == 0, 3.5, 5.5)  # -5 K and -3 K
    air = np.ones(200, bool)
    mean, spread = isa_deviation_k(h, sat, air)
    assert mean == pytest.approx(-4.0, abs=1e-9) and spread == pytest.approx(1.0, abs=1e-9)
    air[MIN_SAT_SAMPLES - 1:] = False
    assert isa_deviation_k(h, sat, air) is None
    assert isa_deviation_k(h, None, np.ones(200, bool)) is None


def test_the_default_result_has_a_height_sd_without_the_joint(tmp_path):
    """Recorder only with the Sabziev fusion alone (no joint smoother), the default result's
    height and its sd come from the pressure height (the end-consistent one of the fusion):
    every airborne sample with a height has a positive sd, and the horizontal sd of the
    fusion's track is there too (docs/sabziev.md, "The track's sd")."""
    from pathlib import Path

    import pandas as pd

    from tests._cli import run_cli

    sample = Path(__file__).resolve().parent.parent / "sample_logs" / "circuit.csv"
    out = tmp_path / "r.csv"
    assert run_cli(["-q", "reconstruct", str(sample), "--no-gnss", "--methods", "sabziev",
                    "-o", str(out)]) == 0
    d = pd.read_csv(out)
    has = d["up_m"].notna() & (d["source"] == "sabziev")
    assert has.sum() > 100
    assert (d.loc[has, "up_sd_m"] > 0).all() and (d.loc[has, "north_sd_m"] > 0).all()
