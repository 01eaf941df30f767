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
