"""A time-of-day column as the log's time: on the epoch's date, never 1900 (issue 49, item 2).

Regression: a mapping whose ``[time]`` format has no date (``%H:%M:%S.%f``) gave stamps on
1900-01-01; with ``epoch_utc`` in the sidecar ``t_s`` came out near -3.9e9 s and the command
exited 0.  The stamps are now put on the epoch's date (rolling over midnight forward); without
an epoch they are seconds of the day with a warning; stamps that cannot be placed are refused
naming the rows.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_ingest_support import handmade_frame, load_quiet

from flightrecon.errors import ValidationError

MAPPING = '[time]\ncolumn = "CLOCK"\nunit = "timestamp"\nformat = "%H:%M:%S.%f"\n'


def _log(tmp_path, start_utc: str, epoch_utc: str | None):
    """The hand-made flight (240 s) stamped with its UTC time of day only, from
    ``start_utc``; a sidecar with ``epoch_utc`` when given."""
    d = handmade_frame()
    ts = pd.Timestamp(start_utc) + pd.to_timedelta(d.t_s, unit="s")
    f = d.drop(columns="t_s").assign(CLOCK=ts.dt.strftime("%H:%M:%S.%f"))
    f.to_csv(tmp_path / "tod.csv", index=False)
    (tmp_path / "tod.toml").write_text(MAPPING)
    if epoch_utc is not None:
        (tmp_path / "tod.meta.toml").write_text(f'[flight]\nepoch_utc = "{epoch_utc}"\n')
    return d, tmp_path / "tod.csv", tmp_path / "tod.toml"


def test_time_of_day_is_on_the_epochs_date(tmp_path):
    """Times of day from 09:00:10 with the epoch 09:00:00 of that day: t_s counts from the
    epoch (10 s after it), not from 1900 (-3.9e9 s before the fix)."""
    d, log, mp = _log(tmp_path, "2026-03-15T09:00:10Z", "2026-03-15T09:00:00Z")
    fl, _ = load_quiet(log, mapping=mp)
    np.testing.assert_allclose(fl.data.t_s, d.t_s + 10.0, atol=1e-6)
    assert fl.meta.epoch_utc == "2026-03-15T09:00:00Z"


def test_time_of_day_rolls_over_midnight_forward(tmp_path):
    """A record across midnight (23:59:00 to 00:03:00): the times after midnight are the next
    day, and the epoch just after midnight puts the first stamps on the day before (the
    date where the first stamp is nearest the epoch)."""
    d, log, mp = _log(tmp_path, "2026-03-15T23:59:00Z", "2026-03-16T00:00:05Z")
    assert d.t_s.iloc[-1] > 65.0                       # the record does cross midnight
    fl, _ = load_quiet(log, mapping=mp)
    t = fl.data.t_s.to_numpy()
    np.testing.assert_allclose(t, d.t_s - 65.0, atol=1e-6)
    assert np.all(np.diff(t) > 0)
    assert any("placed on 2026-03-15" in n for n in fl.meta.ingest.notes)


def test_time_of_day_without_epoch_warns_and_keeps_relative_times(tmp_path):
    """No epoch: the times of day are seconds of an unknown date, with a warning that says
    how to give the date; the UTC epoch stays unknown, never 1900."""
    d, log, mp = _log(tmp_path, "2026-03-15T09:00:10Z", None)
    fl, warns = load_quiet(log, mapping=mp)
    np.testing.assert_allclose(fl.data.t_s, d.t_s + 9 * 3600 + 10.0, atol=1e-6)
    assert fl.meta.epoch_utc is None
    assert any("times of day without a date" in w and "epoch_utc" in w for w in warns)


def test_stamps_before_powered_flight_refused_naming_rows(tmp_path):
    """Dated stamps mixed with ones before 1903 (a corrupt date): refused (exit code 5),
    naming the file, the column and the rows."""
    d = handmade_frame().iloc[:200]
    ts = pd.Timestamp("2026-03-15T09:00:00Z") + pd.to_timedelta(d.t_s, unit="s")
    text = ts.dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ").to_numpy(dtype=object)
    text[[4, 5, 6]] = ["1850-03-15T09:00:01Z", "1850-03-15T09:00:02Z", "1850-03-15T09:00:03Z"]
    d.drop(columns="t_s").assign(CLOCK=text).to_csv(tmp_path / "x.csv", index=False)
    (tmp_path / "x.toml").write_text('[time]\ncolumn = "CLOCK"\nunit = "timestamp"\n')
    with pytest.raises(ValidationError) as exc:
        load_quiet(tmp_path / "x.csv", mapping=tmp_path / "x.toml")
    e = exc.value
    assert e.exit_code == 5 and e.column == "CLOCK"
    assert list(e.rows) == [5, 6, 7]
    assert "1903" in e.message and "x.csv" in str(e)
