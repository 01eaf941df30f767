"""One chi-square verdict on normalised innovations, for every method's health.

A filter whose noise model fits the data produces innovations ``nu`` whose normalised squares
``NIS = nu^T S^-1 nu`` are chi-square distributed with the measurement's dimension as degrees of
freedom; their sum over a flight is chi-square with the total dimension ``D``.  The verdict
compares the mean ``sum(NIS) / D`` (expected 1) with

* the two-sided ``1 - alpha`` band of a chi-square mean, ``chi2.ppf([alpha/2, 1 - alpha/2], D)
  / D``: inside it the filter is *consistent*;
* a gross factor (default 5): above it the noise settings or the motion model misfit the flight
  so badly that the method's uncertainty cannot be trusted, and the method is *unhealthy*.

Real flights are rarely consistent in the strict sense (the band narrows as ``D`` grows, and
the models are tuned conservatively), so only the gross test decides health; the band is
reported.  docs/estimation.md, "Consistency".
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

# the chi-square quantile from scipy.special (chdtri: the inverse survival function) rather than
# scipy.stats.chi2.ppf, the same numbers to 3e-15: importing scipy.stats costs about 1 s of
# every run's start, scipy.special a tenth of it
from scipy.special import chdtri

GROSS_FACTOR = 5.0
"""Mean NIS per degree of freedom above which a method is unhealthy (expected 1)."""


@dataclass(frozen=True)
class ChiSquareVerdict:
    """Result of :func:`chi_square_verdict`.

    Attributes
    ----------
    count : number of finite NIS values used
    dof : total degrees of freedom ``D``
    mean : ``sum(NIS) / D`` (NaN when ``count`` is 0)
    band : two-sided ``1 - alpha`` band of the mean of a chi-square with ``D`` dof
    consistent : ``mean`` inside ``band``
    gross : ``mean`` above ``gross_factor``: the method is unhealthy
    """

    count: int
    dof: float
    mean: float
    band: tuple[float, float]
    consistent: bool
    gross: bool

    def as_dict(self) -> dict[str, Any]:
        """JSON-serialisable form for a method's summary."""
        d = asdict(self)
        d["band"] = list(self.band)
        return d


def chi_square_verdict(nis: Any, dof: Any = 1.0, *, alpha: float = 0.05,
                       gross_factor: float = GROSS_FACTOR) -> ChiSquareVerdict:
    """Chi-square verdict on a set of normalised innovations squared.

    Parameters
    ----------
    nis : array_like
        NIS values, one per measurement (NaN entries, measurements not used, are ignored).
    dof : float or array_like
        Degrees of freedom of each value (the measurement's dimension; 1 for scalars).
    alpha : float
        Two-sided level of the consistency band.
    gross_factor : float
        Mean NIS per degree of freedom above which the verdict is ``gross``.

    Returns
    -------
    ChiSquareVerdict
        With no finite value: ``count`` 0, ``mean`` NaN, neither consistent nor gross (no
        evidence either way).

    Examples
    --------
    >>> v = chi_square_verdict([0.5, 1.2, 0.9, 1.4])
    >>> v.consistent, v.gross
    (True, False)
    """
    x = np.asarray(nis, dtype=float).ravel()
    d = np.broadcast_to(np.asarray(dof, dtype=float).ravel(), x.shape)
    ok = np.isfinite(x) & np.isfinite(d) & (d > 0)
    n = int(ok.sum())
    if n == 0:
        return ChiSquareVerdict(0, 0.0, float("nan"), (float("nan"), float("nan")), False, False)
    D = float(d[ok].sum())
    mean = float(x[ok].sum() / D)
    # chi-square quantiles q(p) = chdtri(D, 1 - p)
    lo, hi = float(chdtri(D, 1.0 - alpha / 2.0)) / D, float(chdtri(D, alpha / 2.0)) / D
    return ChiSquareVerdict(n, D, mean, (lo, hi), bool(lo <= mean <= hi),
                            bool(mean > gross_factor))
