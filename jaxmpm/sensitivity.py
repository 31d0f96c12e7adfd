"""Derivatives of a run's outcome with respect to its continuous inputs.

``jax.grad``, ``jax.jacfwd`` and ``jax.jvp`` work on ``simulate`` directly: every continuous input
(the scene's float fields, the grid spacing ``h`` and the time step ``dt``) reaches the step as a
traced array. This module adds the bookkeeping a study needs: which names are differentiable, and
the gradient of a named error with respect to named parameters.

What the derivative means. A run is piecewise smooth in its parameters. Hat functions have kinks
at nodes, so wherever a query point (a particle centre, a GIMP or CPDI domain edge, an MPQ corner,
a traction point) sits exactly on a node, or crosses one during the run, the outcome has a kink.
Between kinks, ``jax.grad`` is the exact derivative of the smooth piece the parameters lie in. At
a point exactly on a node, the cell to its right is used (``floor``), so the derivative is the
one-sided one from that side. In a central difference, kinks show up as steps whose width shrinks
with the difference step. The gradient tests therefore use generic parameter values, where no
query point lies within the difference step of a node. ``h`` scales the whole problem at fixed
cell count (particles, grid and domain together), so at t = 0 every query point keeps its place
relative to the nodes. ``dt`` is taken at a fixed number of steps, so the final time
``steps * dt`` moves with it, and errors are measured against the exact solution at that time.
"""

from __future__ import annotations

import dataclasses
import inspect
import typing
from collections.abc import Callable, Iterable, Iterator, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.typing import ArrayLike

from ._checks import any_traced, brief, check_bool, check_positive, check_real, is_concrete
from ._simulate import Solution, simulate
from ._step import check_scene
from ._util import as_float
from .interpolators import AbstractInterpolator
from .metrics import _refuse_broken, available_errors, errors
from .particles import State
from .scenes import SCENES, AbstractScene


def continuous_parameters(scene: AbstractScene | type[AbstractScene]) -> tuple[str, ...]:
    """The names a gradient can be taken with respect to.

    Args:
        scene: a scene or a scene class.

    Returns:
        The scene's float parameters but the static ones (``static_parameters``), and ``dt``.

    Raises:
        ValueError: ``scene`` is neither a jaxmpm scene nor a scene class (a registry name such as
            ``"gas-expansion"`` is told the call that makes the scene, ``jm.SCENES[name]()``).
    """
    a_class = isinstance(scene, type) and issubclass(scene, AbstractScene)
    if not isinstance(scene, AbstractScene) and not a_class:
        hint = ""
        if isinstance(scene, str) and scene in SCENES:
            hint = f": jm.SCENES[{scene!r}]() makes that scene (jm.SCENES[{scene!r}] is its class)"
        raise ValueError(
            f"scene must be a jaxmpm scene or scene class such as jm.GasExpansion() or jm.GasExpansion "
            f"(SCENES: {', '.join(SCENES)}), got {brief(scene)}{hint}"
        )
    cls = scene if isinstance(scene, type) else type(scene)
    static = _static_fields(cls)
    return tuple(k for k in _float_parameters(cls) if k not in static) + ("dt",)


def _float_parameters(cls: type[AbstractScene]) -> tuple[str, ...]:
    """The scene class's float parameters, in its order."""
    return tuple(k for k, v in cls.parameters().items() if isinstance(v, float))


def _static_fields(cls: type[AbstractScene]) -> set[str]:
    """The names of the scene class's static fields."""
    return {f.name for f in dataclasses.fields(cls) if f.metadata.get("static", False)}


def static_parameters(scene: AbstractScene | type[AbstractScene]) -> tuple[str, ...]:
    """The scene's float parameters that are static fields: fixed when a run is compiled, because they
    place the particles (the shock tube's and the interface's ``x0``, the Gurney scenes' ``split``:
    which particles belong to which region). No traced value can stand for them, so an ensemble cannot
    vary them in its one compiled call, and neither a gradient nor a fit can take their derivative.

    Args:
        scene: a scene or a scene class.

    Returns:
        The names, in the scene's order (empty for most scenes).
    """
    continuous_parameters(scene)  # refuses what is not a scene
    cls = scene if isinstance(scene, type) else type(scene)
    static = _static_fields(cls)
    return tuple(n for n in _float_parameters(cls) if n in static)


def check_names(scene: AbstractScene, names) -> None:
    """Check names for a gradient.

    Args:
        scene: the scene.
        names: parameter names.

    Raises:
        ValueError: ``scene`` is not a jaxmpm scene (``continuous_parameters``), ``names`` is not a
            sequence of names, no name, or a name that is not a continuous parameter of ``scene`` (or
            ``dt``), or is a static one (``static_parameters``).
    """
    if isinstance(names, str):
        raise ValueError(f"names must be a sequence of parameter names, got the string {names!r}")
    if not isinstance(names, Iterable):
        raise ValueError(f"names must be a sequence of parameter names such as ['beta'], got {brief(names)}")
    if isinstance(names, Iterator):  # used up by these checks: the run would then name nothing
        kind = "a generator" if inspect.isgenerator(names) else f"an iterator ({type(names).__name__})"
        raise ValueError(
            f"names must be a sequence of parameter names such as ['beta'], got {kind}; give list(names)"
        )
    static = static_parameters(scene)
    allowed = continuous_parameters(scene)
    structural = [k for k, v in type(scene).parameters().items() if not isinstance(v, float)]
    for name in names:
        if name in static:
            raise ValueError(
                f"{name} is static in {scene.name} (it places the particles when the run is compiled), so "
                f"it has no gradient; differentiable parameters of {scene.name}: {', '.join(allowed)}"
            )
        if name in structural:
            raise ValueError(
                f"{name} is structural (an integer), so it has no gradient; "
                f"differentiable parameters of {scene.name}: {', '.join(allowed)}"
            )
        if name not in allowed:
            raise ValueError(f"unknown parameter {name!r} for a gradient; allowed: {', '.join(allowed)}")
    if not names:
        raise ValueError(f"name at least one parameter; allowed: {', '.join(allowed)}")


def _check_once(names) -> None:
    """Each name once: a dict of values (and of derivatives) holds one entry per name."""
    names_list = list(names)
    twice = [n for i, n in enumerate(names_list) if n in names_list[:i]]
    if twice:
        raise ValueError(f"names must name each parameter once, got {names!r}: {twice[0]!r} twice")


@typing.no_type_check  # checks every argument itself, raising ValueError, as objective promises
def _measured(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    names: Sequence[str],
    *,
    dt,
    steps: int,
    error: str | Callable[[AbstractScene, Solution], jax.Array],
    **simulate_kwargs,
) -> Callable[[dict[str, ArrayLike]], tuple[jax.Array, State]]:
    """Check what ``objective`` checks before tracing; return ``{name: value} -> (error, state)``, the
    error measured whatever the run's status (that of its last good state where it broke down)."""
    check_scene(scene)
    check_names(scene, names)
    _check_once(names)
    if "dt" in names:  # a traced dt passes simulate's checks: check the value it starts from here
        if np.ndim(dt) != 0:
            raise ValueError(f"dt must be one number (the time step), got shape {np.shape(dt)}")
        check_positive("dt", dt)
    scene_names = [n for n in names if n != "dt"]
    if isinstance(error, str) and error not in available_errors(scene):
        raise ValueError(f"error must be one of the finite errors of {scene.name}: {available_errors(scene)}")
    if not isinstance(error, str) and not callable(error):
        raise ValueError(
            f"error must be one of the finite errors of {scene.name} ({', '.join(available_errors(scene))}) "
            f"or a function (scene, solution) -> scalar, got {brief(error)}"
        )

    def measured(values: dict[str, ArrayLike]) -> tuple[jax.Array, State]:
        if not isinstance(values, dict):
            raise ValueError(f"values must be a dict of parameter name to value, got {brief(values)}")
        missing = [n for n in names if n not in values]
        if missing:
            raise ValueError(
                f"values must hold a value for each of {', '.join(names)}; missing: {', '.join(missing)}"
            )
        other = [k for k in values if k not in names]
        if other:
            raise ValueError(
                f"values names {other[0]!r}, which is not one of {', '.join(names)} (the names this "
                "function was made for)"
            )
        for n in names:
            check_real(f"values[{n!r}]", values[n])
        if "dt" in values and is_concrete(values["dt"]):
            check_positive("dt", values["dt"])
        if all(is_concrete(values[n]) for n in scene_names):  # the scene's own checks (tracers pass)
            dataclasses.replace(scene, **{n: values[n] for n in scene_names})
        where = lambda s: [getattr(s, n) for n in scene_names]
        # as the scene's fields are: 0-d arrays of the float dtype (a tracer passes unchanged)
        sc = eqx.tree_at(where, scene, [as_float(values[n]) for n in scene_names])
        step = values["dt"] if "dt" in values else dt
        sol = simulate(sc, interpolator, dt=step, steps=steps, **simulate_kwargs)
        if callable(error):
            return error(sc, sol), sol.state
        return errors(sc, sol.state, sol.body, allow_broken=True)[error], sol.state

    return measured


def objective(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    names: Sequence[str],
    *,
    dt,
    steps: int,
    error: str | Callable[[AbstractScene, Solution], jax.Array] = "F_rms_rel",
    with_status: bool = False,
    **simulate_kwargs,
) -> Callable[[dict[str, ArrayLike]], jax.Array | tuple[jax.Array, jax.Array]]:
    """A function ``{name: value} -> scalar`` of the named parameters, for ``jax.grad`` and friends.

    A run that broke down (with ``throw=False``; by default ``simulate`` raises) never gives an error
    that passes for a finished run's:

    - by default, where its status is concrete (a plain call, ``jax.grad``, ``jax.jacfwd``) the
      function raises ``ValueError``; where it is traced (under ``jax.vmap`` or ``jax.jit``) the value
      is NaN, and so are its derivatives, for that member only;
    - with ``with_status=True`` the function returns ``(error, status)``: ``status`` is the run's
      status bitmask (0: it finished; ``jaxmpm.status.describe`` says what broke), and a run that
      broke down has the error of its last good state, finite, whose derivatives are that state's.
      Take derivatives with ``jax.grad(f, has_aux=True)`` (or ``jax.jacfwd(f, has_aux=True)``) and
      keep the members whose status is 0.

    Args:
        scene: the scene; parameters not named keep its values.
        interpolator: the interpolator.
        names: parameters to expose (scene float fields and ``dt``), each once.
        dt: the time step (used unless ``"dt"`` is named).
        steps: number of steps.
        error: a key of ``jaxmpm.errors`` or a function ``(scene, solution) -> scalar``.
        with_status: return ``(error, status)`` instead of the error alone.
        **simulate_kwargs: passed to ``simulate`` (transfer, artificial_cells, checkpoint, throw, ...).

    Returns:
        The function of the named parameters: ``values -> error``, or with ``with_status``
        ``values -> (error, status)``.

    Raises:
        ValueError: before anything is traced: ``scene`` is not a jaxmpm scene object (a class or
            a registry name is told how to make one), ``names`` is not a sequence of continuous
            parameter names (an unknown or structural name) or names one twice, ``error`` is neither
            a name of ``available_errors(scene)`` nor a function, or ``with_status`` is not a bool.
            The function raises it for values that are not a dict of exactly ``names`` to real
            numbers, for values the scene refuses (``h <= 0``, a NaN: the scene's own checks, on
            concrete values; tracers pass) or ``dt <= 0``, and for a run that broke down, as above.
    """
    measured = _measured(scene, interpolator, names, dt=dt, steps=steps, error=error, **simulate_kwargs)
    check_bool("with_status", with_status)
    throws = simulate_kwargs.get("throw", True)  # (simulate checks that it is a bool)
    if with_status:

        def with_its_status(values: dict[str, ArrayLike]) -> tuple[jax.Array, jax.Array]:
            value, state = measured(values)
            return value, state.status

        return with_its_status

    def f(values: dict[str, ArrayLike]) -> jax.Array:
        value, state = measured(values)
        if is_concrete(state.status):
            _refuse_broken(
                state, False, "objective() measures a finished run, and this state is", _WITH_STATUS
            )
            return value
        if throws:  # simulate has raised where the run broke down
            return value
        # A member whose run broke down gets NaN, value and derivatives; a healthy one its value plus
        # zeros. The NaN enters through the inputs themselves: through the error alone, a derivative
        # that is exactly zero (an exact initial state) would drop it.
        value = jnp.asarray(value)
        poison = jnp.where(state.status == 0, 0.0, jnp.nan).astype(value.dtype)
        return value + sum(poison * jnp.sum(v).astype(value.dtype) for v in jax.tree.leaves(values))

    return f


_WITH_STATUS = "Pass with_status=True to get the error of that state beside its status."


def gradient(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    names: Sequence[str],
    *,
    dt,
    steps: int,
    error: str | Callable = "F_rms_rel",
    mode: str = "reverse",
    **simulate_kwargs,
) -> dict[str, jax.Array]:
    """The derivative of a run's error with respect to each named parameter.

    A run that broke down (with ``throw=False``; by default ``simulate`` raises) is refused, in
    either mode: its derivative would be that of its last good state, not of the run asked for
    (``objective(..., with_status=True)`` gives that one beside the status).

    Args:
        scene: as for ``objective``.
        interpolator: as for ``objective``.
        names: as for ``objective``.
        dt: as for ``objective``.
        steps: as for ``objective``.
        error: as for ``objective``.
        **simulate_kwargs: as for ``objective``.
        mode: ``"reverse"`` (``jax.grad``; pass ``checkpoint=True`` for long runs) or ``"forward"``
            (``jax.jacfwd``, memory independent of the step count, cost growing with ``len(names)``).

    Returns:
        ``{name: d(error)/d(name)}``.

    Raises:
        ValueError: an unknown mode, a call inside ``jax.jit``, ``jax.vmap`` or ``jax.grad`` (a traced
            scene, ``dt`` or run argument), or what ``objective`` refuses (a scene that is not a
            jaxmpm scene object, bad ``names``, a name given twice, an unknown ``error``), before
            anything is traced; after the run, a run that broke down (``throw=False``) or an error
            that is not finite.
    """
    if mode not in ("reverse", "forward"):
        raise ValueError(f"mode must be 'reverse' or 'forward', got {mode!r}")
    if any_traced((scene, dt, simulate_kwargs)):
        raise ValueError(
            "jm.gradient returns concrete numbers: call it outside jax.jit, jax.vmap and jax.grad (inside "
            "them, differentiate jm.sensitivity.objective with jax.grad or jax.jacfwd)"
        )
    measured = _measured(scene, interpolator, names, dt=dt, steps=steps, error=error, **simulate_kwargs)
    values = {n: as_float(dt if n == "dt" else getattr(scene, n)) for n in names}

    def with_value(values):  # the error rides along, to be read outside the transformation
        value, state = measured(values)
        return value, (value, state)

    d = jax.grad if mode == "reverse" else jax.jacfwd
    derivatives, (value, state) = d(with_value, has_aux=True)(values)
    # outside the transformation, the run's status, steps and time are concrete
    _refuse_broken(
        state,
        False,
        "gradient() differentiates a finished run, and this state is",
        "A smaller dt or fewer steps run to the end; jm.sensitivity.objective(..., with_status=True) "
        "gives the error of the last good state and its status, for jax.grad(..., has_aux=True).",
    )
    if not np.isfinite(float(value)):
        raise ValueError(
            f"gradient() differentiates a finite error, and the error of this run is {float(value)!r}: "
            "its derivatives would mean nothing (check the error function)"
        )
    return derivatives
