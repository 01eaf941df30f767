"""The core's one forward loop and one backward loop (estimation/filtering.py, smoothing.py)
on the linear model: the mean-only pass against the pass with covariances, each pass compiled
with its own step only, and the loops served from numba's disk cache in a new process."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np

from flightrecon.estimation.kalman import LinearModel, kalman_filter, rts_smooth
from flightrecon.estimation.smoothing import backward_pass


def _run(seed: int = 3, N: int = 400):
    rng = np.random.default_rng(seed)
    dt = 0.5
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = 0.2 * np.array([[dt ** 3 / 3, dt ** 2 / 2], [dt ** 2 / 2, dt]])
    z = rng.normal(size=(N, 1)) * 3.0 + np.arange(N)[:, None] * 0.7
    z[rng.random(N) < 0.3] = np.nan            # steps without a plot
    return kalman_filter(np.zeros(2), np.eye(2) * 100.0, F, Q, z, np.array([[1.0, 0.0]]),
                         np.array([[9.0]]))


def test_mean_only_pass_gives_the_covariance_pass_means():
    """x_s = x_f + C P_p^-1 (x_s' - x_p) through the Cholesky solve and C y = P_f F^T y, or
    through the gain G = C P_p^-1 of the full step: the same means; the Cholesky solve of a
    2 x 2 P_p with condition number below 1e6 loses at most 1e-10 relative."""
    run = _run()
    full = rts_smooth(run.x, run.P, run.x_pred, run.P_pred, run.F)
    N, n = run.x.shape
    empty = np.empty((0, 0))
    model = LinearModel(run.F, empty.reshape(0, 0, 0), empty, empty.reshape(0, 0, 0),
                        empty.reshape(0, 0, 0), run.x, run.P, run.x_pred, run.P_pred, empty,
                        empty.reshape(0, 0, 0), np.empty(0), np.empty(0, dtype=np.int64),
                        np.empty((0, n, n)))
    xs = np.empty((N, n))
    assert backward_pass(model, run.x, run.x_pred, xs, None) == 0
    np.testing.assert_allclose(xs, full.x, rtol=1e-10, atol=1e-9)
    assert not np.allclose(xs, run.x)          # it did smooth


def test_each_pass_compiles_its_own_step_once_and_loads_it_from_the_cache(tmp_path):
    """In a process with an empty cache the covariance pass compiles the RTS step and not the
    mean-only solve (``P_last``'s type chooses the step: smoothing.smoothed_step), the linear
    model's geometry stays a compile-time constant (one specialisation of rts_step), and both
    loops are written to the disk cache: a second process loads them without compiling."""
    code = textwrap.dedent("""
        import numpy as np
        from flightrecon.estimation import rts
        from flightrecon.estimation.filtering import forward_pass
        from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run
        from flightrecon.estimation.smoothing import backward_pass
        r = kalman_filter(np.zeros(2), np.eye(2), np.eye(2), 0.1 * np.eye(2),
                          np.ones((20, 1)), np.array([[1.0, 0.0]]), np.eye(1))
        rts_smooth_run(r)
        print(len(rts.rts_mean_solve.signatures),
              ",".join(str(s[0]) for s in rts.rts_step.signatures),
              sum(forward_pass.stats.cache_hits.values()),
              sum(backward_pass.stats.cache_hits.values()))
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=env, check=True).stdout.split() for _ in range(2)]
    assert runs[0] == ["0", "Literal[int](0)", "0", "0"]      # compiled: its own step only
    assert runs[1][-2:] == ["1", "1"]                          # loaded from the cache
