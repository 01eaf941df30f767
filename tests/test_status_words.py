"""Status words that mean what they say (issue 52, item 5): the Sabziev fusion's documented
fallback is ``fallback`` with its figures, not ``ok``; ``healthy`` never beside
``consistent: false`` without the reason; the events' levels are not the console's word
"warning"; a ``fallback`` or ``stopped`` track feeds the default, an ``unhealthy`` one never."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flightrecon.estimation.consistency import chi_square_verdict
from flightrecon.events import SEVERITIES
from flightrecon.pipeline.health import method_health
from flightrecon.pipeline.status import FEEDS_DEFAULT, fallback_note, method_status
from flightrecon.types import MethodResult


def _track(name: str) -> pd.DataFrame:
    t = np.arange(5.0)
    return pd.DataFrame({"t_s": t, f"{name}_north_m": t, f"{name}_east_m": t,
                         f"{name}_north_sd_m": np.ones(5), f"{name}_east_sd_m": np.ones(5)})


def _sabziev_summary(fallback_axes: list[str]) -> dict:
    axes = {a: {"converged": a not in fallback_axes, "fallback": a in fallback_axes,
                "k_used": -0.1 if a in fallback_axes else -0.02,
                "end_correction_m": -3004.0 if a == "x" else 5570.0 if a == "z" else None}
            for a in ("x", "y", "z")}
    return {"converged": True, "healthy": True, "roots_found": not fallback_axes,
            "fallback_axes": fallback_axes, "axes": axes}


def test_a_sabziev_fallback_is_fallback_with_its_axes_and_corrections():
    res = MethodResult("sabziev", _track("sabziev"), _sabziev_summary(["x", "z"]))
    st = method_status(res, method_health(res))
    assert st["status"] == "fallback" and st["status"] in FEEDS_DEFAULT
    assert "2 of 3 axes" in st["reason"]
    assert "north (x, k = -0.1, end correction -3.00 km)" in st["reason"]
    assert "east (z, k = -0.1, end correction +5.57 km)" in st["reason"]


def test_a_sabziev_with_every_root_is_ok_without_a_reason():
    res = MethodResult("sabziev", _track("sabziev"), _sabziev_summary([]))
    st = method_status(res, method_health(res))
    assert st["status"] == "ok" and "reason" not in st
    assert fallback_note(res.summary) is None


def test_an_unhealthy_fallback_is_unhealthy():
    s = _sabziev_summary(["x"])
    s["healthy"], s["health_problems"] = False, ["height 900 m from the pressure height"]
    res = MethodResult("sabziev", _track("sabziev"), s)
    st = method_status(res, method_health(res))
    assert st["status"] == "unhealthy" and st["status"] not in FEEDS_DEFAULT
    assert "900 m" in st["reason"] and st["healthy"] is False


@pytest.mark.parametrize("nis, words", [(0.2, "cautious side"), (1.9, "tighter"),
                                        (7.0, "does not fit")])
def test_consistent_false_always_carries_its_reason(nis, words):
    verdict = chi_square_verdict(np.full(1000, nis))
    assert verdict.consistent is False
    s = {"converged": True, "healthy": not verdict.gross, "consistency": verdict.as_dict()}
    res = MethodResult("sns", _track("sns"), s)
    st = method_status(res, method_health(res))
    assert st["consistency"]["consistent"] is False
    assert words in st["consistency"]["note"]
    assert st["healthy"] is (not verdict.gross)
    if st["healthy"]:
        assert "only a mean above 5" in st["consistency"]["note"]


def test_a_consistent_method_has_no_note():
    verdict = chi_square_verdict(np.ones(1000))
    res = MethodResult("sns", _track("sns"), {"converged": True, "healthy": True,
                                              "consistency": verdict.as_dict()})
    assert "note" not in method_status(res, method_health(res))["consistency"]


def test_the_summarys_healthy_is_the_pipelines_verdict():
    # a method that calls itself healthy but whose track has a hole is unhealthy: the summary's
    # healthy says so, its own verdict kept beside it
    tr = _track("sns")
    tr.loc[2, "sns_north_m"] = np.nan
    res = MethodResult("sns", tr, {"converged": True, "healthy": True})
    st = method_status(res, method_health(res))
    assert st["status"] == "unhealthy" and st["healthy"] is False
    assert st["own_verdict_healthy"] is True


def test_the_events_levels_are_not_the_consoles_word():
    assert "warning" not in SEVERITIES and SEVERITIES == ("info", "caution", "alert")


def test_the_console_counts_alerts_and_cautions():
    from flightrecon.cli.reconstruct import _events_line

    line = _events_line({"events": [{"kind": "exceedance", "severity": "alert"},
                                    {"kind": "gap", "severity": "caution"},
                                    {"kind": "gap", "severity": "caution"}]})
    assert "1 alert(s), 2 caution(s)" in line and "warning" not in line


def test_fallback_and_stopped_feed_the_default_result():
    from flightrecon.pipeline.combine import _horizontal

    results = {m: MethodResult(m, _track(m), {}) for m in ("joint", "sns", "sabziev")}
    status = {"joint": "unhealthy", "sns": "stopped", "sabziev": "fallback"}
    healthy = {m: status[m] in FEEDS_DEFAULT for m in results}
    _, source, names = _horizontal(results, ("joint", "sns", "sabziev"), healthy,
                                   lambda m: results[m].track, 5)
    assert [names[i] for i in source] == ["sns"] * 5
