"""Polarity checks on noisy records, including one that starts airborne (no rest part)."""

from __future__ import annotations

import numpy as np
import pytest
from test_ingest_support import handmade_frame

from flightrecon.errors import ValidationError
from flightrecon.ingest import load_flight


def _noisy(seed: int, airborne_only: bool):
    """The hand-made record with recorder-like noise: 0.01 g on loads, 0.2 deg on attitude,
    0.5 m/s on TAS (seeded); optionally cut to its airborne part (t > 75 s)."""
    rng = np.random.default_rng(seed)
    d = handmade_frame()
    for c, sd in (("n_long_g", 0.01), ("n_lat_g", 0.01), ("n_norm_g", 0.01), ("roll_deg", 0.2),
                  ("pitch_deg", 0.2), ("heading_deg", 0.2), ("tas_mps", 0.5)):
        d[c] = d[c] + sd * rng.standard_normal(len(d))
    d["heading_deg"] = d["heading_deg"] % 360.0
    d["tas_mps"] = d["tas_mps"].abs()
    if airborne_only:
        d = d[d.t_s > 75.0].reset_index(drop=True)
    return d


@pytest.mark.parametrize("airborne_only", [False, True])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noisy_record_passes(tmp_path, seed, airborne_only):
    d = _noisy(seed, airborne_only)
    d.to_csv(tmp_path / "ok.csv", index=False)
    fl = load_flight(tmp_path / "ok.csv")
    assert len(fl.data) == len(d)


@pytest.mark.parametrize("channel,words", [("n_norm_g", "n_norm_g looks flipped"),
                                           ("n_long_g", "n_long_g looks flipped"),
                                           ("roll_deg", "turns against the bank"),
                                           ("heading_deg", "turns against the bank")])
@pytest.mark.parametrize("airborne_only", [False, True])
def test_flipped_channel_detected_in_noisy_record(tmp_path, channel, words, airborne_only):
    d = _noisy(7, airborne_only)
    d[channel] = (-d[channel]) % 360.0 if channel == "heading_deg" else -d[channel]
    d.to_csv(tmp_path / "flip.csv", index=False)
    with pytest.raises(ValidationError, match=words) as ex:
        load_flight(tmp_path / "flip.csv")
    assert ex.value.exit_code == 5


# ---- values outside the physical range: isolated ones repaired, systematic ones refused

def _with_rest_noise_and_spikes(seed: int = 4):
    """The hand-made record (it starts at rest) with airspeed noise around zero at rest (some
    samples negative, as a real air-data computer writes them) and two 40 m/s downward spikes
    at low speed (rows far outside the range)."""
    rng = np.random.default_rng(seed)
    d = handmade_frame()
    tas = d["tas_mps"].to_numpy().copy()
    ok = ~np.isnan(tas)
    tas[ok] += 0.6 * rng.standard_normal(ok.sum())
    slow = np.flatnonzero(ok & (tas < 10.0))
    spikes = slow[[5, len(slow) // 2]]
    tas[spikes] -= 40.0
    d["tas_mps"] = tas
    return d, spikes


def test_rest_noise_and_spikes_are_repaired_and_reported(tmp_path):
    """Negative airspeed noise at rest is clipped to 0, the 40 m/s spikes are masked; both are
    reported with file, column, rows, count and action; cleaning goes on and fills them."""
    from flightrecon.cleaning import clean_flight

    d, spikes = _with_rest_noise_and_spikes()
    tas = d["tas_mps"].to_numpy()
    n_neg_small = int(np.count_nonzero((tas < 0) & (tas >= -2.0)))
    assert n_neg_small >= 5                      # the case is what it claims to be
    d.to_csv(tmp_path / "rest.csv", index=False)
    with pytest.warns(Warning, match="outside the physical range"):
        fl = load_flight(tmp_path / "rest.csv")
    reps = {r["action"]: r for r in fl.meta.ingest.repairs}
    assert set(reps) == {"clipped", "masked"}
    assert reps["masked"]["rows"] == [int(i) + 1 for i in spikes]
    assert reps["masked"]["count"] == 2 and reps["masked"]["column"] == "tas_mps"
    assert reps["clipped"]["count"] == n_neg_small
    assert reps["masked"]["file"].endswith("rest.csv")
    v = fl.data["tas_mps"].to_numpy()
    assert np.nanmin(v) == 0.0 and np.isnan(v[spikes]).all()
    cf = clean_flight(fl)
    acts = [e for e in cf.report if e["action"] in ("range_clip", "range_mask")]
    assert [e["action"] for e in acts] == ["range_clip", "range_mask"]
    assert acts[1]["file_rows"] == [int(i) + 1 for i in spikes]
    # the grid has airspeed everywhere (the masked samples bridged as short gaps)
    assert cf.grid["tas_mps"].notna().all() and (cf.grid["tas_mps"] >= 0).all()


def test_wrong_unit_still_refused(tmp_path):
    """Airspeed written in km/h under a name that says m/s stays in range; written in ft/min it
    is far out of range on most samples: refused, naming the fix."""
    d = handmade_frame()
    d["tas_mps"] = d["tas_mps"] / 0.00508          # ft/min
    d.to_csv(tmp_path / "fpm.csv", index=False)
    with pytest.raises(ValidationError, match="systematically.*unit = 'ft/min'"):
        load_flight(tmp_path / "fpm.csv")


def test_impact_load_clipped(tmp_path):
    """A load factor just beyond the range (a sensor saturating) is clipped, not masked."""
    d = handmade_frame()
    i = int(np.flatnonzero(d["n_norm_g"].notna().to_numpy())[-3])
    d.loc[i, "n_norm_g"] = 10.3
    d.to_csv(tmp_path / "imp.csv", index=False)
    with pytest.warns(Warning, match="clipped"):
        fl = load_flight(tmp_path / "imp.csv")
    assert fl.data["n_norm_g"].iloc[i] == 10.0
    assert fl.meta.ingest.repairs[0]["action"] == "clipped"
