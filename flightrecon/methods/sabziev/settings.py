"""Settings of the Sabziev fusion method beyond its coefficients (docs/sabziev.md, "The
adapter"; the coefficients ``k``, ``k_sd`` and ``strict`` are fields of
:class:`flightrecon.pipeline.ReconstructSettings`)."""

from __future__ import annotations

from dataclasses import dataclass

from flightrecon.methods.sabziev.axis import KT_MAX


@dataclass(frozen=True)
class SabzievSettings:
    """Numerical settings of :func:`flightrecon.methods.sabziev.method.run_sabziev`.

    Attributes
    ----------
    hold : how the inputs are held between grid samples (``linear`` or ``zero``; see
        :func:`flightrecon.methods.sabziev.fuse`)
    tol_m : end-point miss [m] below which the Newton-Raphson iterations stop
    max_iter : iteration cap per phase
    vertical_rule : root selection for k2 on the oscillatory branch (``baro``: the root whose
        track stays closest to the pressure height; ``slowest``); docs/sabziev.md
    kt_max : overflow guard on ``k t`` (:data:`flightrecon.methods.sabziev.axis.KT_MAX`)
    policy : ``stable`` (default: roots in the stable range, a fixed stable coefficient with a
        linear end correction where there is none, the pressure height made consistent with
        the end points) or ``paper`` (both branches, NaN without a root); docs/sabziev.md
    """

    hold: str = "linear"
    tol_m: float = 1e-3
    max_iter: int = 60
    vertical_rule: str = "baro"
    kt_max: float = KT_MAX
    policy: str = "stable"
