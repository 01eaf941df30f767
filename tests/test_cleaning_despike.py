"""Despiking (flightrecon.cleaning.despike and the Despike step): acceptance on synthetic
recorder channels with injected spikes, transients kept, plateaus untouched, speed."""

import time

import numpy as np
import pandas as pd
import pytest
from test_cleaning_synth import TD_S, synthetic_flight

from flightrecon.cleaning import DespikeSettings, despike_samples, estimate_quantum
from flightrecon.cleaning.steps import Despike, UnwrapAngles, run_steps

# noise sigma and quantisation step the synthetic recorder uses for each channel
NOISE = {"n_long_g": (0.003, 0.001), "n_lat_g": (0.003, 0.001), "n_norm_g": (0.003, 0.001),
         "roll_deg": (0.05, 0.01), "pitch_deg": (0.05, 0.01), "heading_deg": (0.05, 0.1),
         "tas_mps": (0.3, 0.1), "baro_alt_m": (1.0, 0.3048)}


def _inject(data, rng, frac=0.002):
    """Single- and double-sample spikes of 10-50 x max(noise, step) at ``frac`` of the samples."""
    out = data.copy()
    truth = {}
    for c, (sd, q) in NOISE.items():
        v = out[c].to_numpy(dtype=float).copy()
        ok = np.flatnonzero(np.isfinite(v))
        k = max(int(frac * len(ok)), 5)
        # keep spikes 20 samples apart and away from the ends, so each is isolated; a random
        # lattice offset per channel keeps the channels' spikes independent of each other
        lattice = np.arange(20, len(ok) - 20, 20) + rng.integers(0, 20)
        pos = rng.choice(lattice[lattice < len(ok) - 20], size=k, replace=False)
        double = rng.random(k) < 0.25
        amp = rng.uniform(10, 50, k) * max(sd, q) * rng.choice([-1, 1], k)
        rows = list(ok[pos]) + list(ok[pos[double] + 1])
        v[ok[pos]] += amp
        v[ok[pos[double] + 1]] += amp[double]
        if c == "heading_deg":
            v = np.where(np.isfinite(v), v % 360.0, v)
        out[c] = v
        truth[c] = np.array(sorted(rows))
    return out, truth


@pytest.mark.parametrize("seed", [0, 1])
def test_injected_spikes_caught_and_clean_samples_kept(seed):
    """Acceptance: >= 95 % of injected spikes removed, < 0.1 % of clean samples altered, and
    every removed sample named (time and row) in the report."""
    flight, _ = synthetic_flight(seed)
    rng = np.random.default_rng(100 + seed)
    dirty, truth = _inject(flight.data, rng)
    before = dirty.copy()
    out, rep = run_steps(dirty, [UnwrapAngles(), Despike()])
    pd.testing.assert_frame_equal(dirty, before)  # the input is not mutated
    removed = {r["channel"]: set(r["rows"]) for r in rep if r["action"] == "despike"}
    caught = total = false_alarm = n_clean = 0
    for c, rows in truth.items():
        got = removed.get(c, set())
        caught += len(got & set(rows))
        total += len(rows)
        n_clean += int(np.isfinite(dirty[c].to_numpy(dtype=float)).sum()) - len(rows)
        false_alarm += len(got - set(rows))
        # the report names each removed sample, and exactly those are missing in the output
        was = np.isfinite(dirty[c].to_numpy(dtype=float))
        now = np.isfinite(out[c].to_numpy(dtype=float))
        assert set(np.flatnonzero(was & ~now)) == got
    assert caught / total >= 0.95, (caught, total)
    assert false_alarm / n_clean < 1e-3, (false_alarm, n_clean)


def test_two_g_touchdown_kept():
    """A 2 g touchdown spike is data: one-sample spike seen by two load channels (kept by the
    coincidence rule), or a three-sample excursion in n_norm alone (kept by the run rule)."""
    flight, _ = synthetic_flight(3)
    d = flight.data.copy()
    i = int(np.flatnonzero(np.isclose(d["t_s"], TD_S + 0.5, atol=1 / 32))[0])
    d.loc[i, "n_norm_g"] = 2.0
    d.loc[i, "n_long_g"] = d.loc[i, "n_long_g"] - 0.3
    out, rep = run_steps(d, [Despike()])
    assert out.loc[i, "n_norm_g"] == 2.0 and np.isfinite(out.loc[i, "n_long_g"])
    kept = [r for r in rep if r["action"] == "keep_coincident_transient"]
    assert any(r["channel"] == "n_norm_g" and i in r["rows"] for r in kept)
    d2 = flight.data.copy()
    d2.loc[i:i + 2, "n_norm_g"] = [1.6, 2.0, 1.5]
    out2, _ = run_steps(d2, [Despike()])
    np.testing.assert_array_equal(out2.loc[i:i + 2, "n_norm_g"], [1.6, 2.0, 1.5])


def test_quantised_plateau_and_steps_not_flagged():
    """A quantised channel sitting on a plateau with one-step flicker, and a lasting step,
    are not spikes (MAD = 0 on the plateau: the floor is the quantisation step)."""
    x = np.full(2000, 100.0)
    x[500::37] += 0.25  # single-step flicker
    x[1200:] = 180.0  # a lasting jump
    x = np.round(x / 0.25) * 0.25
    assert estimate_quantum(x) == pytest.approx(0.25)
    _, spikes, _ = despike_samples(x)
    assert not spikes.any()


def test_real_spike_on_plateau_flagged_and_run_of_three_kept():
    x = np.full(500, 7.0)
    x[5::50] += 0.1  # one-step flicker: tells the quantisation step (0.1) to the estimator
    x[100] = 9.0
    x[200:202] = 5.0
    x[300:303] = 9.0
    _, spikes, _ = despike_samples(x, DespikeSettings(max_run=2))
    assert np.flatnonzero(spikes).tolist() == [100, 200, 201]


def test_unwrapped_heading_spike_across_north():
    """A spike on a heading that crosses 360 -> 0 is found on the unwrapped series."""
    t = np.arange(800) / 16.0
    h = (350.0 + 1.0 * t) % 360.0  # turning through north
    h[400] = (h[400] + 40.0) % 360.0
    d = pd.DataFrame({"t_s": t, "heading_deg": h})
    out, rep = run_steps(d, [UnwrapAngles(), Despike()])
    assert [r["rows"] for r in rep if r["action"] == "despike"] == [[400]]
    assert np.all(np.abs(np.diff(out["heading_deg"].dropna())) < 1.0)


def test_speed_576k():
    rng = np.random.default_rng(5)
    n = 576_000
    x = np.round((1.0 + 0.05 * np.sin(np.arange(n) / 500) + rng.normal(0, 0.003, n)) / 0.001) * 0.001
    t0 = time.perf_counter()
    despike_samples(x)
    # two pandas rolling medians: ~0.5 s here; 10 s allows a loaded 2-core machine
    assert time.perf_counter() - t0 < 10.0


def test_running_median_kernel_equals_pandas(monkeypatch):
    """The numba sorted-window kernel and the plain numpy running median (short series) give
    the same numbers as pandas' centred rolling median (ends truncated), for odd and even
    effective windows and many ties."""
    from flightrecon.cleaning import despike
    from flightrecon.cleaning.despike import _running_median, _running_median_kernel

    rng = np.random.default_rng(9)
    for n in (1, 2, 5, 15, 16, 301):
        x = np.round(rng.normal(0, 1, n), 1)
        for w in (0, 1, 7):
            ref = pd.Series(x).rolling(2 * w + 1, center=True, min_periods=1).median()
            np.testing.assert_array_equal(_running_median_kernel(x, w), ref.to_numpy())
            for limit in (0, n):   # compiled, numpy
                monkeypatch.setattr(despike, "NUMPY_MEDIAN_MAX_SAMPLES", limit)
                np.testing.assert_array_equal(_running_median(x, w), ref.to_numpy())


def _spiky(rng, n, quantum):
    x = 0.2 * np.sin(np.arange(n) / 40.0) + rng.normal(0, 0.01, n)
    if quantum:
        x = np.round(x / quantum) * quantum
    i = rng.choice(n, max(n // 50, 1), replace=False)
    x[i] += rng.choice([-1.0, 1.0], len(i)) * rng.uniform(0.1, 1.0, len(i))
    return x


def test_sparse_threshold_gives_the_same_candidates_and_spikes():
    """``hampel_candidates(full_threshold=False)`` (the running MAD evaluated only where a
    sample can exceed the threshold at all) gives exactly the candidates and spikes of the full
    evaluation, the exact threshold at every candidate and never more than it elsewhere."""
    from flightrecon.cleaning.despike import hampel_candidates, isolated_runs

    rng = np.random.default_rng(11)
    s = DespikeSettings()
    cases = [_spiky(rng, n, q) for n in (3, 4, 16, 17, 40, 5000) for q in (0.0, 0.01)]
    cases += [np.zeros(50), np.r_[np.zeros(30), 1.0, np.zeros(30)]]
    for x in cases:
        c_full, t_full, f_full = hampel_candidates(x, s)
        c_fast, t_fast, f_fast = hampel_candidates(x, s, full_threshold=False)
        assert f_fast == f_full
        np.testing.assert_array_equal(c_fast, c_full)
        np.testing.assert_array_equal(t_fast[c_full], t_full[c_full])
        assert np.all(t_fast <= t_full)
        np.testing.assert_array_equal(isolated_runs(x, c_fast, t_fast, s.max_run),
                                      isolated_runs(x, c_full, t_full, s.max_run))
    assert sum(hampel_candidates(x, s)[0].sum() for x in cases) > 50  # the test has spikes


def test_median_at_equals_running_median(monkeypatch):
    """The pointwise window median equals the running median at the same samples, ends
    (truncated, even-length windows) included, whole windows sorted in one block or several;
    a read-only channel gives the same running median as a writable copy."""
    from flightrecon.cleaning import despike
    from flightrecon.cleaning.despike import _median_at, _running_median, _running_median_kernel

    rng = np.random.default_rng(12)
    for block in (65536, 3):
        monkeypatch.setattr(despike, "_MEDIAN_BLOCK", block)
        for n in (1, 2, 9, 15, 16, 200):
            x = np.round(rng.normal(0, 1, n), 1)
            idx = np.arange(n)
            for w in (0, 1, 7):
                ref = _running_median_kernel(x, w)
                np.testing.assert_array_equal(_median_at(x, idx, w), ref)
                some = rng.permutation(n)[: n // 2]
                np.testing.assert_array_equal(_median_at(x, some, w), ref[some])
    monkeypatch.setattr(despike, "NUMPY_MEDIAN_MAX_SAMPLES", 0)   # the compiled path
    x = rng.normal(0, 1, 50)
    ro = x.copy()
    ro.flags.writeable = False
    np.testing.assert_array_equal(_running_median(ro, 7), _running_median(x, 7))


def test_estimate_quantum_equals_distinct_value_spacing():
    """The sort-based quantum equals the smallest spacing of ``numpy.unique`` values (ties,
    signed zeros, NaN, a single distinct value, values near the 1e-9 relative cut-off)."""
    rng = np.random.default_rng(13)

    def reference(x):
        u = np.unique(x[np.isfinite(x)])
        if len(u) < 2:
            return 0.0
        d = np.diff(u)
        d = d[d > 1e-9 * max(float(np.max(np.abs(u))), 1.0)]
        return float(d.min()) if len(d) else 0.0

    cases = [np.round(rng.normal(0, 5, 1000) / 0.25) * 0.25, rng.normal(0, 1, 500),
             np.array([-0.0, 0.0, 0.0]), np.array([3.0]), np.array([np.nan, 2.0, np.inf]),
             np.array([1e12, 1e12 + 1e-4, 1e12 + 2.0]), np.array([1.0, 1.0 + 1e-10, 2.0]),
             np.array([-7.0, 2.0, np.nan, 2.0, 5.5])]
    for x in cases:
        assert estimate_quantum(x) == reference(x)
