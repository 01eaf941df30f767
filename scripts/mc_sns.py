"""Monte Carlo study of the SNS dead-reckoning filter and smoother (docs/methods.md, section 4).

Writes ``docs/tables/sns_*.md`` and ``docs/figures/sns_*.png``.  Fixed seeds; run from the
repository root::

    /tmp/venv/bin/python scripts/mc_sns.py            # full size (about 2-4 minutes)
    /tmp/venv/bin/python scripts/mc_sns.py --runs 20  # quick look

The generator (:func:`simulate`) is self-consistent with the filter's model: the truth is flown
with the recorder readings held between samples (ground velocity = air velocity + wind), in the
moving local-level frame; the sensors carry the systematic errors of docs/methods.md section 4
(heading bias, wind error, Doppler scale, drift bias) drawn from the filter's priors, plus
white noise per sample; GNSS fixes at 1 Hz, offset from the recorder grid, with the antenna on a
lever arm.
The tests (``tests/test_sns_mc.py``) import this module.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.methods import sns as core
from flightrecon.methods.sns.method import radii_with_height, solve_sns
from flightrecon.types import CleanFlight, FlightMeta, Position

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

G0 = 9.80665
LEVER_ARM_M = (6.0, 0.5, -2.0)


@dataclass(frozen=True)
class SimFlight:
    """A simulated flight: the cleaned input and the truth.

    ``lat``/``lon`` (rad) and ``v_ne`` (m/s) are the true centre-of-mass position and ground
    velocity at the grid times; ``corr`` (N, 3) the true corrections at the grid times (state
    order of the model): a draw from the prior plus the random walk the filter assumes.
    """

    clean: CleanFlight
    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    v_ne: np.ndarray
    corr: np.ndarray
    model: int


def heading_profile(rng: np.random.Generator, duration_s: float, rate_hz: float,
                    turn_rate_dps: float = 3.0, leg_s: tuple[float, float] = (120.0, 300.0)
                    ) -> np.ndarray:
    """True heading [deg] on the grid: straight legs joined by turns of +-90 or +-180 deg."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    psi = np.empty_like(t)
    h = rng.uniform(0, 360)
    t0 = 0.0
    knots_t, knots_h = [0.0], [h]
    while t0 < duration_s:
        t0 += rng.uniform(*leg_s)
        knots_t.append(t0)
        knots_h.append(h)
        turn = rng.choice([-180.0, -90.0, 90.0, 180.0])
        t0 += abs(turn) / turn_rate_dps
        h += turn
        knots_t.append(t0)
        knots_h.append(h)
    psi[:] = np.interp(t, knots_t, knots_h)
    return psi


def _integrate_latlon(lat0: float, lon0: float, dn: np.ndarray, de: np.ndarray, h: float):
    """Latitude/longitude after cumulative north/east steps (held velocities), vectorised.

    Two fixed-point passes of the mid-latitude radii (relative error ~1e-12 per step).
    """
    lat = np.full(len(dn) + 1, lat0)
    for _ in range(3):
        latm = 0.5 * (lat[:-1] + lat[1:])
        mh, nh = radii_with_height(latm, h)
        lat = lat0 + np.concatenate([[0.0], np.cumsum(dn / mh)])
    latm = 0.5 * (lat[:-1] + lat[1:])
    mh, nh = radii_with_height(latm, h)
    lon = lon0 + np.concatenate([[0.0], np.cumsum(de / (nh * np.cos(latm)))])
    return lat, lon


def simulate(seed: int, *, model: int = core.MODEL_AIRSPEED, duration_s: float = 3600.0,
             rate_hz: float = 2.0, gaps: tuple[tuple[float, float], ...] = (),
             noise: core.SnsNoise | None = None, alt_m: float = 9000.0) -> SimFlight:
    """A seeded flight with turns, sensor errors drawn from the priors and GNSS fixes.

    Parameters
    ----------
    seed : random seed
    model : which sensors to give (heading-airspeed with a wind channel, or heading-Doppler)
    duration_s, rate_hz : length and recorder rate (noise in ``noise`` is per sample)
    gaps : GNSS dropouts ``(start_s, length_s)``
    """
    rng = np.random.default_rng(seed)
    noise = noise or core.default_noise(model)
    psi_deg = heading_profile(rng, duration_s, rate_hz)
    n = len(psi_deg)
    dt = 1.0 / rate_hz
    t = np.arange(n) * dt
    psi = np.deg2rad(psi_deg)
    tas = 200.0 + 20.0 * np.sin(2 * np.pi * t / 1800.0 + rng.uniform(0, 6.3))
    wspd, wdir = rng.uniform(5.0, 40.0), rng.uniform(0, 2 * np.pi)
    wind = wspd * np.array([np.cos(wdir), np.sin(wdir)])   # blowing toward
    vg = tas[:, None] * np.column_stack([np.cos(psi), np.sin(psi)]) + wind
    lat0, lon0 = np.deg2rad(rng.uniform(-60, 60)), np.deg2rad(rng.uniform(-180, 180))
    # truth flown with the velocity held over [t_j, t_j+1)
    lat, lon = _integrate_latlon(lat0, lon0, vg[:, 0] * dt, vg[:, 1] * dt, alt_m)
    lat, lon = lat[:-1], lon[:-1]
    sd = noise.sensor_sd
    pri = np.asarray(noise.prior_sd)
    steps = rng.standard_normal((n, 3)) * np.sqrt(np.asarray(noise.rw_q) * dt)
    steps[0] = 0.0
    corr = rng.normal(0.0, pri) + np.cumsum(steps, axis=0)
    e = rng.standard_normal((n, 4))
    omega = np.gradient(psi, t)
    roll = np.rad2deg(np.arctan(tas * omega / G0))
    grid = {"t_s": t, "tas_mps": tas + sd[0] * e[:, 0] if model == core.MODEL_AIRSPEED else tas,
            "roll_deg": roll, "pitch_deg": np.full(n, 2.0)}
    if model == core.MODEL_AIRSPEED:
        grid["heading_deg"] = np.rad2deg(psi - corr[:, 2] + sd[1] * e[:, 1])
        wr = wind - corr[:, :2] + np.column_stack([sd[2] * e[:, 2], sd[3] * e[:, 3]])
        grid["wind_speed_mps"] = np.hypot(wr[:, 0], wr[:, 1])
        grid["wind_from_deg"] = np.rad2deg(np.arctan2(-wr[:, 1], -wr[:, 0])) % 360.0
    else:
        gs = np.hypot(vg[:, 0], vg[:, 1])
        track = np.unwrap(np.arctan2(vg[:, 1], vg[:, 0]))
        psi_meas = psi - corr[:, 2] + sd[2] * e[:, 2]
        drift_meas = (track - psi) - corr[:, 1] + sd[1] * e[:, 1]
        grid["heading_deg"] = np.rad2deg(psi_meas)
        grid["doppler_gs_mps"] = gs / (1.0 + corr[:, 0]) + sd[0] * e[:, 0]
        grid["drift_deg"] = np.rad2deg(drift_meas)
    grid_df = pd.DataFrame(grid)
    # GNSS at 1 Hz, 0.3 s after the grid seconds, antenna on the lever arm
    tf = np.arange(0.3, t[-1], 1.0)
    for g0, glen in gaps:
        tf = tf[(tf < g0) | (tf >= g0 + glen)]
    j = np.searchsorted(t, tf, side="right") - 1
    tau = tf - t[j]
    mh, nh = radii_with_height(lat[j], alt_m)
    from flightrecon.methods.sns.method import lever_arm_ne
    arm = lever_arm_ne(grid_df, LEVER_ARM_M)
    darm = np.gradient(arm, t, axis=0)
    armf = np.column_stack([np.interp(tf, t, arm[:, i]) for i in range(2)])
    darmf = np.column_stack([np.interp(tf, t, darm[:, i]) for i in range(2)])
    dn = vg[j, 0] * tau + armf[:, 0] + noise.pos_sd_m * rng.standard_normal(len(tf))
    de = vg[j, 1] * tau + armf[:, 1] + noise.pos_sd_m * rng.standard_normal(len(tf))
    glat = lat[j] + dn / mh
    glon = lon[j] + de / (nh * np.cos(lat[j]))
    gv = vg[j] + darmf + noise.vel_sd_mps * rng.standard_normal((len(tf), 2))
    gnss = pd.DataFrame({"t_s": tf, "gnss_lat_deg": np.rad2deg(glat),
                         "gnss_lon_deg": np.rad2deg(glon), "gnss_alt_m": np.full(len(tf), alt_m),
                         "gnss_vn_mps": gv[:, 0], "gnss_ve_mps": gv[:, 1]})
    meta = FlightMeta(departure=Position(float(np.rad2deg(lat0)), float(np.rad2deg(lon0)), 0.0),
                      gnss_lever_arm_m=LEVER_ARM_M)
    clean = CleanFlight(grid=grid_df, rate_hz=rate_hz, gnss=gnss, radar=pd.DataFrame(),
                        meta=meta)
    return SimFlight(clean, t, lat, lon, vg, corr, model)


def state_errors(sim: SimFlight, x: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Truth minus estimate (N, 5) at filter points ``idx``: north/east metres, corrections."""
    lat_t, lon_t = sim.lat[idx], sim.lon[idx]
    latm = 0.5 * (lat_t + x[:, 0])
    mh, nh = radii_with_height(latm, 9000.0)
    err = np.empty((len(idx), 5))
    err[:, 0] = (lat_t - x[:, 0]) * mh
    err[:, 1] = (lon_t - x[:, 1]) * nh * np.cos(latm)
    err[:, 2:] = sim.corr[idx] - x[:, 2:]
    return err


def nees(err: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared per row, ``e^T P^-1 e`` via a solve."""
    return np.einsum("ni,ni->n", err, np.linalg.solve(P, err[..., None])[..., 0])


def run_case(seed: int, *, model: int, form: str, duration_s: float = 3600.0,
             gaps: tuple[tuple[float, float], ...] = ()):
    """Simulate, filter, smooth: (sim, solution, filtered errors, smoothed errors)."""
    sim = simulate(seed, model=model, duration_s=duration_s, gaps=gaps)
    sol = solve_sns(sim.clean, form=form, model="doppler" if model else "airspeed")
    ef = state_errors(sim, sol.run.x, sol.idx)
    es = state_errors(sim, sol.smoothed.x, sol.idx)
    return sim, sol, ef, es


def coverage_study(runs: int, *, model: int, duration_s: float = 3600.0, seed0: int = 1000):
    """Per run: final smoothed correction error / reported sd, and the heading sd [deg]."""
    z = np.empty((runs, 3))
    psi_sd = np.empty(runs)
    track_z = np.empty(runs)
    for r in range(runs):
        _sim, sol, _ef, es = run_case(seed0 + r, model=model, form="consistent",
                                    duration_s=duration_s)
        P = sol.smoothed.P[-1]
        z[r] = es[-1, 2:] / np.sqrt(np.diag(P)[2:])
        psi_sd[r] = np.rad2deg(np.sqrt(P[4, 4]))
        track_z[r] = (es[-1, 3] + es[-1, 4]) / np.sqrt(P[3, 3] + P[4, 4] + 2 * P[3, 4])
    return z, psi_sd, track_z


def nees_study(runs: int, *, model: int, duration_s: float = 3600.0, seed0: int = 2000,
               every_s: float = 30.0):
    """Run-averaged NEES of the filtered state at check times, for both forms.

    Returns ``{form: (check times, averaged NEES, RMS filtered horizontal position error)}``.
    """
    out = {}
    for form in ("consistent", "seed"):
        acc = None
        sq = 0.0
        cnt = 0
        for r in range(runs):
            _sim, sol, ef, _es = run_case(seed0 + r, model=model, form=form,
                                          duration_s=duration_s)
            step = max(1, round(every_s * 2.0))
            k = np.arange(step, len(sol.idx), step)
            v = nees(ef[k], sol.run.P[k])
            acc = v if acc is None else acc + v
            sq += float(np.sum(ef[:, :2] ** 2))
            cnt += len(ef)
        out[form] = (sol.inputs.t[k], acc / runs, np.sqrt(sq / cnt))
    return out


def nees_band(runs: int, dof: int = 5, p: float = 0.95) -> tuple[float, float]:
    """Two-sided band of the run-average of chi-square(dof) NEES values."""
    from scipy.stats import chi2

    lo, hi = chi2.ppf([(1 - p) / 2, (1 + p) / 2], runs * dof)
    return lo / runs, hi / runs


GAPS = ((900.0, 30.0), (1700.0, 120.0), (2600.0, 600.0))


def gap_study(runs: int, *, model: int = core.MODEL_AIRSPEED, seed0: int = 3000):
    """Position error inside/outside the GNSS gaps of :data:`GAPS`, filter vs smoother."""
    rows = {g: {"f_end": [], "s_mid": [], "s_max": [], "f_out": [], "s_out": [],
                "s_cov": [], "f_cov": []} for g in GAPS}
    example = None
    for r in range(runs):
        _sim, sol, ef, es = run_case(seed0 + r, model=model, form="consistent", gaps=GAPS)
        t = sol.inputs.t
        ef_n = np.hypot(ef[:, 0], ef[:, 1])
        es_n = np.hypot(es[:, 0], es[:, 1])
        ingap = np.zeros(len(t), bool)
        for g0, gl in GAPS:
            ingap |= (t >= g0) & (t < g0 + gl)
        sdf = np.sqrt(sol.run.P[:, [0, 1], [0, 1]])
        sds = np.sqrt(sol.smoothed.P[:, [0, 1], [0, 1]])
        for g0, gl in GAPS:
            m = (t >= g0) & (t < g0 + gl)
            kend = np.flatnonzero(m)[-1]
            kmid = np.flatnonzero(m)[len(np.flatnonzero(m)) // 2]
            d = rows[(g0, gl)]
            d["f_end"].append(ef_n[kend])
            d["s_mid"].append(es_n[kmid])
            d["s_max"].append(es_n[m].max())
            d["f_out"].append(np.sqrt(np.mean(ef_n[~ingap] ** 2)))
            d["s_out"].append(np.sqrt(np.mean(es_n[~ingap] ** 2)))
            d["s_cov"].append(np.mean(np.abs(es[m, :2]) <= 2 * sds[m]))
            d["f_cov"].append(np.mean(np.abs(ef[m, :2]) <= 2 * sdf[m]))
        if example is None:
            example = (t, ef, es, sdf, sds)
    return rows, example


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="Monte Carlo runs per study")
    ap.add_argument("--out", type=Path, default=Path("docs"))
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    R = args.runs
    tables = args.out / "tables"
    figs = args.out / "figures"
    tables.mkdir(parents=True, exist_ok=True)
    figs.mkdir(parents=True, exist_ok=True)

    # 1. coverage of the corrections
    names = {core.MODEL_AIRSPEED: ["wind corr north", "wind corr east", "heading corr"],
             core.MODEL_DOPPLER: ["Doppler scale corr", "drift corr", "heading corr"]}
    rows = []
    for model in (core.MODEL_AIRSPEED, core.MODEL_DOPPLER):
        z, psi_sd, track_z = coverage_study(R, model=model)
        label = "heading-airspeed" if model == core.MODEL_AIRSPEED else "heading-Doppler"
        for i, nm in enumerate(names[model]):
            rows.append([label, nm, f"{100 * np.mean(np.abs(z[:, i]) <= 2):.1f}",
                         f"{np.std(z[:, i]):.2f}", f"{np.mean(z[:, i]):+.2f}"])
        if model == core.MODEL_DOPPLER:
            rows.append([label, "track corr (drift + heading)",
                         f"{100 * np.mean(np.abs(track_z) <= 2):.1f}", f"{np.std(track_z):.2f}",
                         f"{np.mean(track_z):+.2f}"])
        rows.append([label, "heading corr sd [deg], median / max",
                     f"{np.median(psi_sd):.3f} / {np.max(psi_sd):.3f}", "", ""])
    (tables / "sns_coverage.md").write_text(
        header()
        + f"Coverage of the reported 2-sigma intervals of the smoothed corrections at the end of "
        f"a 1-hour flight with turns of 90-180 deg ({R} runs per model, seeds 1000+).  "
        f"z = error / reported sd.\n\n"
        + _md_table(["model", "quantity", "2-sigma coverage [%]", "sd of z", "mean of z"], rows))

    # 2. NEES consistent vs seed
    nrows = []
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    lo, hi = nees_band(R)
    for ax, model in zip(axes, (core.MODEL_AIRSPEED, core.MODEL_DOPPLER)):
        res = nees_study(R, model=model)
        label = "heading-airspeed" if model == core.MODEL_AIRSPEED else "heading-Doppler"
        for form, (tt, v, prms) in res.items():
            inside = np.mean((v >= lo) & (v <= hi))
            nrows.append([label, form, f"{np.mean(v):.2f}", f"{100 * inside:.0f}",
                          f"{prms:.2f}"])
            ax.plot(tt / 60, v, label=form)
        ax.axhspan(lo, hi, color="0.85", label="95 % band")
        ax.set_yscale("log")
        ax.set_xlabel("time [min]")
        ax.set_ylabel(f"NEES averaged over {R} runs (5 states)")
        ax.set_title(label)
        ax.legend()
    fig.tight_layout()
    fig.savefig(figs / "sns_nees.png", dpi=110)
    plt.close(fig)
    (tables / "sns_nees.md").write_text(
        header()
        + f"Run-averaged NEES of the filtered 5-state (position, three corrections), every 30 s "
        f"of a 1-hour flight, {R} runs (seeds 2000+).  95 % band for the average of {R} "
        f"chi-square(5) values: [{lo:.2f}, {hi:.2f}]; expected 5.\n\n"
        + _md_table(["model", "form", "time-mean of averaged NEES", "% check times in band",
                     "RMS filtered horizontal position error [m]"], nrows))

    # 3. GNSS gaps
    gr, ex = gap_study(R)
    grows = []
    for (g0, gl), d in gr.items():
        grows.append([f"{gl:.0f} s at {g0:.0f} s", f"{np.mean(d['f_end']):.1f}",
                      f"{np.mean(d['s_mid']):.1f}", f"{np.mean(d['s_max']):.1f}",
                      f"{100 * np.mean(d['f_cov']):.1f}", f"{100 * np.mean(d['s_cov']):.1f}",
                      f"{np.mean(d['f_out']):.2f}", f"{np.mean(d['s_out']):.2f}"])
    (tables / "sns_gaps.md").write_text(
        header()
        + f"GNSS dropouts in a 1-hour heading-airspeed flight, {R} runs (seeds 3000+).  Horizontal "
        f"position error norms [m], averaged over runs; coverage = share of in-gap samples and "
        f"components with |error| <= 2 reported sd.\n\n"
        + _md_table(["gap", "filter err at gap end", "smoother err mid-gap",
                     "smoother max err in gap", "filter 2-sd coverage in gap [%]",
                     "smoother 2-sd coverage in gap [%]", "filter RMS outside gaps",
                     "smoother RMS outside gaps"], grows))
    t, ef, es, sdf, sds = ex
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for ax, (g0, gl) in zip(axes, GAPS):
        m = (t >= g0 - 0.5 * gl - 30) & (t < g0 + 1.5 * gl + 30)
        ax.plot(t[m], ef[m, 0], "C0", lw=1, label="filter error north")
        ax.fill_between(t[m], -2 * sdf[m, 0], 2 * sdf[m, 0], color="C0", alpha=0.2)
        ax.plot(t[m], es[m, 0], "C1", lw=1, label="smoother error north")
        ax.fill_between(t[m], -2 * sds[m, 0], 2 * sds[m, 0], color="C1", alpha=0.3)
        ax.axvspan(g0, g0 + gl, color="0.9", zorder=0)
        ax.set_title(f"{gl:.0f} s gap (shaded); bands are 2 sd")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("north error [m]")
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(figs / "sns_gaps.png", dpi=110)
    plt.close(fig)
    print((tables / "sns_coverage.md").read_text())
    print((tables / "sns_nees.md").read_text())
    print((tables / "sns_gaps.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
