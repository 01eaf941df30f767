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
the time steps, only what happens at one step.  The protocol is the ten functions below, each
with its real signature and what an implementation must do (``k`` the step index 0 .. N-1,
``x`` (n,) and ``P`` (n, n) the state and covariance updated in place):

* forward (filter): :func:`workspace`, :func:`predict_into`, :func:`keep_predicted`,
  :func:`update_into`, :func:`keep_filtered`;
* backward (Rauch-Tung-Striebel smoother, :mod:`flightrecon.estimation.rts`):
  :func:`smoothing_covariances`, :func:`cross_transposed_into`, :func:`cross_times_into`
  (mean-only pass only), :func:`rts_frame`, :func:`keep_smoothed`.

:class:`Model` is the type of the model argument.  Inside a compiled loop numba replaces each
call by the implementation registered for the model's class (a class without one is a typing
error naming the function and the class); called from plain Python the functions raise.  For a
type checker :func:`implements` gives each implementation its protocol function's signature.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any, NoReturn, ParamSpec, Protocol, TypeVar

import numpy as np
import numpy.typing as npt
from numba.core import types
from numba.extending import overload

__all__ = [
    "FloatArray",
    "Model",
    "ModelT",
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


FloatArray = npt.NDArray[np.float64]
_Params = ParamSpec("_Params")
_Result = TypeVar("_Result")


class Model(Protocol):
    """What every model is: a :class:`typing.NamedTuple` of arrays (its transition's inputs, its
    measurements, its noise and the buffers its outputs go to) whose class selects the
    implementations of the protocol functions (:func:`implements`)."""

    @property
    def _fields(self) -> tuple[str, ...]: ...


#: the model argument of the protocol functions: an implementation annotates its own class
ModelT = TypeVar("ModelT", bound=Model)


def _compiled_only(name: str) -> NoReturn:
    raise NotImplementedError(f"{name} runs only inside the core's compiled loops, as the "
                              "implementation registered for the model's class "
                              "(estimation.model.implements)")


def workspace(model: ModelT) -> Any:
    """The model's per-run scratch (any value numba can type; passed back as ``ws`` to the
    step functions).  Called once per pass, before the first step."""
    _compiled_only("workspace")


def predict_into(model: ModelT, k: int, x: FloatArray, P: FloatArray, ws: Any) -> None:
    """The prediction from step ``k-1`` to step ``k`` (k >= 1), in place:
    ``x <- f_k(x)``, ``P <- F_k P F_k^T + Q_k`` (or the model's correlated-noise form)."""
    _compiled_only("predict_into")


def keep_predicted(model: ModelT, k: int, x: FloatArray, P: FloatArray) -> None:
    """Store the prediction of step ``k`` (``x_pred[0]`` is the prior ``x0``) in the model's
    buffers, dense or packed, or not at all (dense ones with
    :func:`flightrecon.estimation.filtering.keep_dense_into`)."""
    _compiled_only("keep_predicted")


def update_into(model: ModelT, k: int, x: FloatArray, P: FloatArray, ws: Any) -> None:
    """Every measurement update of step ``k``, in place, with the core's update functions
    (:mod:`flightrecon.estimation.updates`), recording the model's innovations."""
    _compiled_only("update_into")


def keep_filtered(model: ModelT, k: int, x: FloatArray, P: FloatArray) -> None:
    """Store the filtered estimate of step ``k`` in the model's buffers."""
    _compiled_only("keep_filtered")


def smoothing_covariances(model: ModelT, k: int, ws: Any) -> tuple[FloatArray, FloatArray]:
    """``(P_f[k], P_p[k+1])`` as (n, n) arrays (unpacked or recomputed as the model stored
    them); may prepare the step's transition in ``ws`` for :func:`cross_transposed_into` and
    :func:`cross_times_into`, which follow it."""
    _compiled_only("smoothing_covariances")


def cross_transposed_into(model: ModelT, k: int, CT: FloatArray, ws: Any) -> None:
    """``CT <- C^T`` (n, n), the transposed cross-covariance ``Cov(x_k, x_{k+1} | Y_0..k)^T``
    (``F_{k+1} P_f[k]`` for a plain transition)."""
    _compiled_only("cross_transposed_into")


def cross_times_into(model: ModelT, k: int, y: FloatArray, out: FloatArray, ws: Any) -> None:
    """``out <- C y`` (n,), the mean-only pass's product computed in the model's structure
    (needed only by a class registered :func:`with_mean_only_pass`)."""
    _compiled_only("cross_times_into")


def rts_frame(model: ModelT, k: int) -> tuple[int, float, float, float]:
    """``(geometry, h_k, h_k+1, rel_tol)``: the state's geometry
    (:mod:`flightrecon.estimation.manifold`, a module constant: inlined, it stays a
    compile-time constant of the loop), the heights [m] for a latitude/longitude state, and the
    Cholesky pivot tolerance."""
    _compiled_only("rts_frame")


def keep_smoothed(model: ModelT, k: int, x_s: FloatArray, P_s: FloatArray, with_cov: bool,
                  ws: Any) -> None:
    """The model's outputs at step ``k`` from the smoothed state ``x_s`` (and covariance
    ``P_s`` when ``with_cov``; an empty ``P_s`` in the mean-only pass), residuals included."""
    _compiled_only("keep_smoothed")


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


def implements(function: Callable[_Params, _Result], model_class: type, *,
               refcounted: bool = True, forceinline: bool = False
               ) -> Callable[[Callable[_Params, _Result]], Callable[_Params, _Result]]:
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

    For a type checker the returned ``impl`` has ``function``'s signature (an annotated
    implementation that differs from the protocol is an error).
    """
    def register(impl: Callable[_Params, _Result]) -> Callable[_Params, _Result]:
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
