"""Every ``flightrecon simulate`` scenario of both truth sources through ``flightrecon
reconstruct`` (issue #21's acceptance): no written result has a non-finite position (the
default result on every row; a method's track, under its prefix, over its whole span: never all
NaN, no holes), and an exit status 0 always comes with a track (a non-zero exit writes no
result).

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

from flightrecon.cli.main import main
from flightrecon.sim import simulate, write_simulation

POSITION = re.compile(r"(^|_)((north|east|up)_m|lat_deg|lon_deg|alt_m)$")
"""Position columns of a result, with or without a method prefix (not their ``_sd_m``)."""

SLOW = pytest.mark.slow
ALL_NAN_SABZIEV = pytest.mark.xfail(
    reason="known (measured 2026-12-01 on main with the method-health rule): exit 0 and a "
           "finite default result, but the unhealthy Sabziev fit's track is written under its "
           "prefix with every position NaN (issue 21 item 3: only finite tracks are written)",
    strict=False)
"""The cases that failed this way when the test was written; the others passed."""
CASES = [
    pytest.param("circuit", {}, id="circuit"),
    pytest.param("regional", {}, id="regional", marks=[SLOW, ALL_NAN_SABZIEV]),
    pytest.param("seed-ads-arms", {}, id="seed-ads-arms"),
    pytest.param("landing", {}, id="landing"),
    pytest.param("longhaul", {"duration_s": 4000.0}, id="longhaul-4000s",
                 marks=[SLOW, ALL_NAN_SABZIEV]),
]
_KNOWN = {"jsbsim-circuit-gnss", "jsbsim-circuit-recorder-only", "jsbsim-spiral-gnss",
          "jsbsim-spiral-recorder-only", "jsbsim-spin-gnss"}
for _name, _scale, _slow in (("jsbsim-circuit", 1.0, False), ("jsbsim-xc", 0.12, True),
                             ("jsbsim-jet", 0.05, True), ("jsbsim-spiral", 0.1, False),
                             ("jsbsim-spin", 0.1, False)):
    for _gnss in (1.0, 0.0):
        _id = f"{_name}-{'gnss' if _gnss else 'recorder-only'}"
        CASES.append(pytest.param(
            _name, {"scale": _scale, "gnss_hz": _gnss}, id=_id,
            marks=([SLOW] if _slow else []) + ([ALL_NAN_SABZIEV] if _id in _KNOWN else [])))


def run_cli(args: list[str]) -> int:
    try:
        main(["--quiet", *args])
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0


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
    # the default result: a finite position on every row
    bad = {c: int((~np.isfinite(df[c].to_numpy(float))).sum()) for c in default}
    bad = {c: n for c, n in bad.items() if n}
    assert not bad, f"non-finite default positions written (column: rows): {bad}"
    # a method's track (its prefix) may cover less than the record (Sabziev and dead
    # reckoning start at lift-off), but is never all NaN and has no NaN inside its span
    for c in sorted(set(cols) - set(default)):
        ok = np.isfinite(df[c].to_numpy(float))
        assert ok.any(), f"{c}: a written track with every position non-finite"
        first, last = np.flatnonzero(ok)[[0, -1]]
        holes = int((~ok[first:last + 1]).sum())
        assert holes == 0, f"{c}: {holes} non-finite positions inside its span"
