"""Every ``flightrecon simulate`` scenario of both truth sources through ``flightrecon
reconstruct`` (issue #21's acceptance): no written result has a non-finite position, and an
exit status 0 always comes with a track (a non-zero exit writes no result).

The JSBSim scenarios run as short versions (``scale``), with their default GNSS and recorder
only (no GNSS: the departure and the arrival airfield, or the wreckage, are the only absolute
positions).  The long records (``regional``, ``longhaul`` shortened to 4000 s, the JSBSim
cross-country and jet) are marked slow.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli

from flightrecon.sim import simulate, write_simulation

POSITION = re.compile(r"(^|_)((north|east|up)_m|lat_deg|lon_deg|alt_m)$")
"""Position columns of a result, with or without a method prefix (not their ``_sd_m``)."""

SLOW = pytest.mark.slow
CASES = [
    pytest.param("circuit", {}, id="circuit"),
    pytest.param("regional", {}, id="regional", marks=SLOW),
    pytest.param("seed-ads-arms", {}, id="seed-ads-arms"),
    pytest.param("landing", {}, id="landing"),
    pytest.param("longhaul", {"duration_s": 4000.0}, id="longhaul-4000s", marks=SLOW),
]
for _name, _scale, _slow in (("jsbsim-circuit", 1.0, False), ("jsbsim-xc", 0.12, True),
                             ("jsbsim-jet", 0.05, True), ("jsbsim-spiral", 0.1, False),
                             ("jsbsim-spin", 0.1, False)):
    for _gnss in (1.0, 0.0):
        CASES.append(pytest.param(
            _name, {"scale": _scale, "gnss_hz": _gnss},
            id=f"{_name}-{'gnss' if _gnss else 'recorder-only'}",
            marks=[SLOW] if _slow else []))


@pytest.mark.parametrize(("scenario", "overrides"), CASES)
def test_reconstruct_every_scenario(scenario, overrides, tmp_path):
    if scenario.startswith("jsbsim-"):
        pytest.importorskip("jsbsim")
    log = tmp_path / "x.parquet"
    write_simulation(simulate(scenario, 3, **overrides), log)
    out = tmp_path / "x.recon.csv"
    code = run_cli(["reconstruct", str(log), "-o", str(out)])
    if code != 0:
        # nothing reconstructed: said so with a non-zero exit, and no result left behind
        assert not out.exists(), f"exit {code} but {out.name} was written"
        return
    assert out.exists(), "exit 0 without a result"
    df = pd.read_csv(out)
    assert len(df) > 0, "exit 0 with an empty result"
    cols = [c for c in df.columns if POSITION.search(c)]
    default = ["north_m", "east_m", "up_m", "lat_deg", "lon_deg", "alt_m"]
    assert set(default) <= set(cols)
    # the default result: finite on every row
    bad = {c: int((~np.isfinite(df[c].to_numpy(float))).sum()) for c in default}
    bad = {c: n for c, n in bad.items() if n}
    assert not bad, f"non-finite default positions written (column: rows): {bad}"
    # a method's own columns cover its interval (Sabziev: lift-off to touchdown) and are
    # empty outside it (docs/output.md); inside it, never a hole
    for c in set(cols) - set(default):
        fin = np.isfinite(df[c].to_numpy(float))
        if fin.any():
            i0, i1 = np.flatnonzero(fin)[[0, -1]]
            assert fin[i0:i1 + 1].all(), f"{c}: non-finite positions inside its coverage"
