"""Merge separate measurement files (GNSS, radar) onto the recorder's time base.

docs/schema.md ("Two kinds of channel"): a measurement is used once, at its own time.  So each fix
or plot stays one row at its own time: if its time coincides with a recorder row (within
:data:`COINCIDENT_S`) it is written on that row; otherwise it becomes a new row whose input
channels are NaN.  Nothing is interpolated.  The result is sorted by time (stable).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["COINCIDENT_S", "Rows", "merge_rows"]

#: two times closer than this are the same instant (1 microsecond: below any recorder's time
#: resolution, far above float64 rounding of a 10-hour time in seconds, about 1e-11 s)
COINCIDENT_S = 1e-6


@dataclass(frozen=True)
class Rows:
    """Columns of a table plus row provenance (time-major, all arrays of length N)."""

    t: np.ndarray
    values: dict[str, np.ndarray]
    src_file: np.ndarray
    row: np.ndarray
    nan_text: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(self.t.size)


def _column(d: dict[str, np.ndarray], name: str, n: int, fill) -> np.ndarray:
    v = d.get(name)
    if v is None:
        return np.full(n, fill, dtype=np.float64 if isinstance(fill, float) else bool)
    return v


def merge_rows(base: Rows, add: Rows, tol: float = COINCIDENT_S) -> Rows:
    """Merge the rows of ``add`` (a measurement file) into ``base`` (sorted by time).

    Parameters
    ----------
    base : recorder rows, sorted by ``t`` (non-decreasing)
    add : measurement rows, strictly increasing ``t``, columns disjoint from ``base``'s
    tol : coincidence tolerance [s]

    Returns
    -------
    Rows
        ``base`` with ``add``'s values on coinciding rows and ``add``'s other rows inserted,
        sorted by time (stable: a recorder row stays before a new row at the same time).
    """
    nb, na = len(base), len(add)
    idx = np.searchsorted(base.t, add.t)
    left = np.clip(idx - 1, 0, max(nb - 1, 0))
    right = np.clip(idx, 0, max(nb - 1, 0))
    if nb:
        dl = np.abs(base.t[left] - add.t)
        dr = np.abs(base.t[right] - add.t)
        near = np.where(dr <= dl, right, left)
        matched = np.minimum(dl, dr) <= tol
    else:
        near = np.zeros(na, dtype=np.int64)
        matched = np.zeros(na, dtype=bool)
    # a base row can take one fix only; a second fix within tol of the same row gets its own row
    if matched.any():
        _, first = np.unique(near[matched], return_index=True)
        keep = np.zeros(int(matched.sum()), dtype=bool)
        keep[first] = True
        mi = np.flatnonzero(matched)
        matched[mi[~keep]] = False
    new = ~matched
    nn = int(new.sum())
    values: dict[str, np.ndarray] = {}
    for name in set(base.values) | set(add.values):
        b = _column(base.values, name, nb, np.nan).copy()
        a = _column(add.values, name, na, np.nan)
        if name in add.values:
            b[near[matched]] = a[matched]
        values[name] = np.concatenate([b, a[new] if name in add.values else np.full(nn, np.nan)])
    nan_text: dict[str, np.ndarray] = {}
    for name in set(base.nan_text) | set(add.nan_text):
        b = _column(base.nan_text, name, nb, False).copy()
        a = _column(add.nan_text, name, na, False)
        if name in add.nan_text:
            b[near[matched]] = a[matched]
        nan_text[name] = np.concatenate([b, a[new] if name in add.nan_text
                                         else np.zeros(nn, dtype=bool)])
    t = np.concatenate([base.t, add.t[new]])
    src = np.concatenate([base.src_file, add.src_file[new]])
    row = np.concatenate([base.row, add.row[new]])
    order = np.argsort(t, kind="stable")
    return Rows(t=t[order], values={k: v[order] for k, v in values.items()},
                src_file=src[order], row=row[order],
                nan_text={k: v[order] for k, v in nan_text.items()})
