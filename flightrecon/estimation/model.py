"""What a method supplies to the core's forward filter and backward smoother: its model.

A model is a :class:`typing.NamedTuple` of arrays (its transition's inputs, its measurements,
its noise, and the buffers its outputs go to); its class is its identity.  The method implements
each function below for its own class with numba's :func:`numba.extending.overload`
(:func:`implements` is the short form), and the core's loops
(:func:`flightrecon.estimation.filtering.forward_pass`,
:func:`flightrecon.estimation.smoothing.backward_pass`) call them; numba compiles each loop once
per model class with the model's functions inside it, as if written there, and caches it.

This is Stone Soup's separation (transition model, measurement model, predictor, updater,
smoother) in compiled form: the time loops exist once, in the core; a model holds no loop over
the time steps, only what happens at one step.  The functions, with ``k`` the step index
(0 .. N-1), ``x`` (n,) and ``P`` (n, n) the state and covariance updated in place:

Forward (filter):

* ``workspace(model)``: the model's per-run scratch (any value; passed back as ``ws``);
* ``predict_into(model, k, x, P, ws)``: the prediction from step k-1 to step k (k >= 1),
  ``x <- f_k(x)``, ``P <- F_k P F_k^T + Q_k`` (or the model's correlated-noise form);
* ``keep_predicted(model, k, x, P)``: store the prediction of step k (the model's buffers, dense
  or packed, or not at all);
* ``update_into(model, k, x, P, ws)``: every measurement update of step k, with the core's update
  functions (:mod:`flightrecon.estimation.updates`), recording the model's innovations;
* ``keep_filtered(model, k, x, P)``: store the filtered estimate of step k.

Backward (Rauch-Tung-Striebel smoother, :mod:`flightrecon.estimation.rts`):

* ``smoothing_covariances(model, k, ws)``: ``(P_f[k], P_p[k+1])`` as (n, n) arrays (unpacked
  or recomputed as the model stored them); it may prepare the step's transition in ``ws`` for
  the two functions that follow;
* ``cross_transposed_into(model, k, CT, ws)``: ``C^T`` (n, n), the transposed cross-covariance
  ``Cov(x_k, x_{k+1} | Y_0..k)^T`` (``F_{k+1} P_f[k]`` for a plain transition);
* ``cross_times_into(model, k, y, out, ws)``: ``out = C y`` (the mean-only pass's product,
  computed in the model's structure);
* ``rts_frame(model, k)``: ``(geometry, h_k, h_k+1, rel_tol)``: the state's geometry
  (:mod:`flightrecon.estimation.manifold`, a module constant: inlined, it stays a compile-time
  constant), the heights for a latitude/longitude state, and the Cholesky pivot tolerance;
* ``keep_smoothed(model, k, x_s, P_s, with_cov, ws)``: the model's outputs at step k from the
  smoothed state (and covariance when ``with_cov``: an empty ``P_s`` in the mean-only pass),
  residuals included.

The functions below are the names the core calls; calling one with a class that did not
implement it is a typing error naming the function and the class.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from numba.core import types
from numba.extending import overload

__all__ = [
    "cross_times_into",
    "cross_transposed_into",
    "implements",
    "keep_filtered",
    "keep_predicted",
    "keep_smoothed",
    "mean_only_pass_offered",
    "predict_into",
    "rts_frame",
    "smoothing_covariances",
    "update_into",
    "with_mean_only_pass",
    "workspace",
]


def _protocol(name: str) -> Callable[..., Any]:
    def fn(*args: Any) -> Any:
        raise NotImplementedError(f"{name} is compiled per model class (estimation.model)")
    fn.__name__ = fn.__qualname__ = name
    fn.__doc__ = f"The model's ``{name}`` (module docstring); implemented per model class."
    return fn


workspace = _protocol("workspace")
predict_into = _protocol("predict_into")
keep_predicted = _protocol("keep_predicted")
update_into = _protocol("update_into")
keep_filtered = _protocol("keep_filtered")
smoothing_covariances = _protocol("smoothing_covariances")
cross_transposed_into = _protocol("cross_transposed_into")
cross_times_into = _protocol("cross_times_into")
rts_frame = _protocol("rts_frame")
keep_smoothed = _protocol("keep_smoothed")


#: the protocol functions that numba inlines into the core's loops at its IR level: their
#: results are constants of the model class (the geometry), which then stay compile-time
#: constants in the loop (``rts_step`` compiles only that geometry's branch)
INLINED = ("rts_frame",)


def _jit_options(refcounted: bool, forceinline: bool) -> dict[str, Any]:
    """Compile options of a model function: ``nogil``, cached; without numba's reference
    counting where the model says so (``_nrt=False``: measured on the SNS filter, the per-step
    calls' reference counting of the model's some 70 arrays took 38 % of its run; numba's own
    flag, whose absence in a numba version falls back to counting)."""
    opts: dict[str, Any] = {"nogil": True, "cache": True}
    if not refcounted:
        from numba.core.options import DefaultOptions

        if hasattr(DefaultOptions, "_nrt"):
            opts["_nrt"] = False
    if forceinline:
        opts["forceinline"] = True
    return opts


def implements(function: Callable[..., Any], model_class: type, *,
               refcounted: bool = True, forceinline: bool = False
               ) -> Callable[[Callable], Callable]:
    """Register ``impl`` as ``function`` (one of this module's) for models of ``model_class``.

    ``impl`` is a plain Python function with the protocol's arguments, written in the subset
    numba compiles; it is compiled (``nogil``, cached) into the core's loops for that class::

        @implements(predict_into, LinearModel)
        def _predict(model, k, x, P, ws):
            ...

    ``refcounted=False`` for a per-step function that allocates nothing and returns no array
    (it works in the model's and the workspace's buffers): it is compiled without numba's
    reference counting, which otherwise counts every array of the model up and down on each
    call (numba refuses to compile an allocation there: the guard is the compiler's).  A
    function that allocates (e.g. through ``joseph_update``) must stay counted, or what it
    allocates would never be freed.

    With ``forceinline`` LLVM inlines ``impl`` into the loop (numba's ``forceinline``): no call
    per step, whose arguments (every array of the model and the workspace, flattened) cost a
    large model a measurable part of its step.
    """
    def register(impl: Callable) -> Callable:
        def typer(model: Any, *args: Any) -> Callable | None:
            if (isinstance(model, types.BaseNamedTuple)  # type: ignore[attr-defined]
                    and model.instance_class is model_class):
                return impl
            return None
        typer.__name__ = f"{function.__name__}_{model_class.__name__}"
        typer.__signature__ = inspect.signature(impl)  # type: ignore[attr-defined]
        if function.__name__ in INLINED:
            overload(function, inline="always", jit_options={"nogil": True})(typer)
        else:
            overload(function, jit_options=_jit_options(refcounted, forceinline))(typer)
        return impl
    return register


#: the model classes whose backward pass may run without covariances (:func:`with_mean_only_pass`)
_MEAN_ONLY_CLASSES: set[type] = set()


def with_mean_only_pass(model_class: type) -> type:
    """Class decorator: ``model_class`` offers the mean-only backward pass
    (:func:`flightrecon.estimation.smoothing.backward_pass` with an empty ``P_last``; it must
    implement ``cross_times_into``).  Its loop then holds both steps in one compilation, chosen
    at run time; a class without it compiles only the covariance step."""
    _MEAN_ONLY_CLASSES.add(model_class)
    return model_class


def mean_only_pass_offered(model_class: type | None) -> bool:
    """True when ``model_class`` was registered with :func:`with_mean_only_pass`."""
    return model_class in _MEAN_ONLY_CLASSES
