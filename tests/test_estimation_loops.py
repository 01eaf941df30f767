"""The core's one forward loop and one backward loop (estimation/filtering.py, smoothing.py)
on the linear model: the mean-only pass against the pass with covariances, both passes one
compilation, and the loops served from numba's disk cache in a new process."""

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
    full = rts_smooth(run.x, run.P, run.x_pred, run.P_pred, run.diagnostics["F"])
    N, n = run.x.shape
    empty = np.empty((0, 0))
    model = LinearModel(run.diagnostics["F"], empty.reshape(0, 0, 0), empty, empty.reshape(0, 0, 0),
                        empty.reshape(0, 0, 0), run.x, run.P, run.x_pred, run.P_pred, empty,
                        empty.reshape(0, 0, 0), np.empty(0), np.empty(0, dtype=np.int64),
                        np.empty((0, n, n)))
    xs = np.empty((N, n))
    assert backward_pass(model, run.x, run.x_pred, xs, np.empty((0, 0))) == 0
    np.testing.assert_allclose(xs, full.x, rtol=1e-10, atol=1e-9)
    assert not np.allclose(xs, run.x)          # it did smooth


def test_both_passes_are_one_compilation_loaded_from_the_cache(tmp_path):
    """In a process with an empty cache the covariance pass and the mean-only pass of a model
    class registered ``with_mean_only_pass`` are one compilation of the backward loop (the step
    chosen at run time by the running covariance's shape: smoothing.smoothed_step), rts_step
    is compiled only inside the step (inlined at numba's IR level: no compilation of its own),
    the linear model's geometry stays a compile-time constant there (the geometry's minus is
    compiled for the constant only), and both loops are written to the disk cache: a second
    process loads them without compiling."""
    code = textwrap.dedent("""
        import numpy as np
        from flightrecon.estimation import manifold, rts
        from flightrecon.estimation.filtering import forward_pass
        from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run
        from flightrecon.estimation.smoothing import backward_pass
        r = kalman_filter(np.zeros(2), np.eye(2), np.eye(2), 0.1 * np.eye(2),
                          np.ones((20, 1)), np.array([[1.0, 0.0]]), np.eye(1))
        rts_smooth_run(r)
        xs = np.empty_like(r.x)
        backward_pass(r.model, r.x, r.x_pred, xs, np.empty((0, 0)))
        print(len(backward_pass.signatures), len(rts.rts_step.signatures),
              ",".join(str(s[0]) for s in manifold.state_minus_into.signatures),
              sum(forward_pass.stats.cache_hits.values()),
              sum(backward_pass.stats.cache_hits.values()))
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=env, check=True).stdout.split() for _ in range(2)]
    assert runs[0] == ["1", "0", "Literal[int](0)", "0", "0"]  # one loop for both passes
    assert runs[1][-2:] == ["1", "1"]                          # loaded from the cache


def test_mean_only_pass_is_offered_by_the_models_that_use_it():
    """The joint smoother's iterations and the linear worked example run the mean-only pass;
    the SNS filter always smooths with covariances, so its loop has no mean-only step."""
    from flightrecon.estimation.model import mean_only_pass_offered
    from flightrecon.estimation.smoothing import mean_only_pass
    from flightrecon.methods.joint.model import JointModel
    from flightrecon.methods.sns.filter import SnsModel

    assert mean_only_pass_offered(JointModel) and mean_only_pass_offered(LinearModel)
    assert not mean_only_pass_offered(SnsModel)
    assert mean_only_pass(_run().model)
