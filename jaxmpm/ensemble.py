"""Ensembles: many parameter sets in one compiled, ``vmap``-ed call, sharded over every local device.

``ensemble(scene, interpolator, vary={"gamma": array, "P0": array}, dt=..., steps=...)`` runs one
member per row of ``vary`` (the other parameters keep ``scene``'s values). Every member carries its
own status: a member that breaks down stops where it broke (its last good state kept) while the
others finish. The batch is laid out over all local devices with ``jax.sharding`` (a 1D mesh over the
member axis; the batch is padded to a multiple of the device count and the padding dropped), so the
same call uses one CPU, four forced host devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=4``) or every GPU of a machine.

Several hosts: start each process with ``jax.distributed.initialize()`` (coordinator address, process
count and id from the cluster's environment, e.g. SLURM), then call ``ensemble(..., devices=
jax.devices())``: the mesh then spans every host's devices and each process computes its own shard.
Every process gets every member's status (``Ensemble.status``, ``failures``); gather the states with
``jax.experimental.multihost_utils.process_allgather``.
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from . import _memory
from . import status as st_bits
from ._checks import any_traced, brief, check_keywords, is_real
from ._simulate import Solution, as_devices, checkpoint_block, prepare, run_scan, simulate
from ._step import check_scene
from .calibrate import unused
from .interpolators import AbstractInterpolator
from .long_run import computed
from .scenes import AbstractScene
from .sensitivity import continuous_parameters, static_parameters


@dataclasses.dataclass
class Ensemble:
    """The result of ``ensemble``.

    Attributes:
        params: the varied parameters, name to array ``(members,)``.
        solution: a ``Solution`` whose arrays have a leading member axis.
        status: the status bitmask per member (0: healthy).
        devices: how many devices the batch was spread over.
    """

    params: dict
    solution: Solution
    status: np.ndarray
    devices: int

    @property
    def ok(self) -> np.ndarray:
        """Whether each member ran to the end (status 0)."""
        return self.status == 0

    def failures(self) -> list[dict]:
        """The members that broke down.

        Returns:
            One dict per such member: ``member``, ``step``, ``particle``, ``quantities`` and its
            ``params``.
        """
        out = []
        st = self.solution.state
        for i in np.flatnonzero(self.status):
            out.append(
                dict(
                    member=int(i),
                    step=int(st.fail_step[i]),
                    particle=int(st.fail_particle[i]),
                    quantities=st_bits.describe(int(self.status[i])),
                    params={k: float(v[i]) for k, v in self.params.items()},
                )
            )
        return out

    def member_scene(self, scene: AbstractScene, i: int | np.integer | jax.Array) -> AbstractScene:
        """Member ``i``'s scene: ``scene`` (the one given to ``ensemble``) with the member's values of
        the varied scene parameters, for measuring the member against its own exact solution.

        The varied run settings (``RUN_NAMES``: ``dt``, ``t_end``, ``cfl``) are not scene parameters
        and are left out; member ``i``'s own are ``params[name][i]`` (its solution's ``ts`` and state
        ``t`` are already those of its own run).

        Args:
            scene: the ensemble's scene.
            i: the member, as for ``member``.

        Returns:
            The scene with ``params[name][i]`` for each varied scene parameter ``name``.

        Raises:
            ValueError: ``scene`` is not a jaxmpm scene or lacks a varied scene parameter; ``i`` as for
                ``member``.
        """
        k = self._index(i)
        if not isinstance(scene, AbstractScene):
            raise ValueError(f"scene must be the ensemble's jaxmpm scene, got {brief(scene)}")
        varied = {name: v for name, v in self.params.items() if name not in RUN_NAMES}
        missing = [name for name in varied if not hasattr(scene, name)]
        if missing:
            raise ValueError(f"scene must be the ensemble's, and {scene.name} has no {', '.join(missing)}")
        return dataclasses.replace(scene, **{name: float(v[k]) for name, v in varied.items()})

    def member(self, i: int | np.integer | jax.Array) -> Solution:
        """One member's solution.

        Args:
            i: the member, an integer (a Python or NumPy one, or a 0-d integer array) from 0 to
                ``members - 1``; a negative index counts from the end, as for a Python sequence (-1 is
                the last member).

        Returns:
            Member ``i``'s ``Solution``, as ``simulate`` would return it.

        Raises:
            ValueError: ``i`` is not an integer (a bool is not one) or not a member's index (from
                ``-members`` to ``members - 1``).
        """
        k = self._index(i)
        return jax.tree_util.tree_map(lambda a: a[k], self.solution)

    def _index(self, i) -> int:
        """``i`` as a member's index, or the ``ValueError`` of ``member``."""
        n = len(self.status)
        try:  # a Python or NumPy integer, or a concrete 0-d integer array
            k = None if isinstance(i, bool | np.bool_) else operator.index(i)
        except TypeError:
            k = None
        if k is None or not -n <= k < n:
            raise ValueError(
                f"i must be a member's index, an integer from 0 to {n - 1} (or from {-n} to -1, "
                f"counting from the end) for this ensemble of {n} members, got {brief(i)}"
            )
        return k


def variable_parameters(scene: AbstractScene | type[AbstractScene]) -> tuple[str, ...]:
    """The scene's parameters that ``ensemble``'s ``vary`` may name (besides the run's ``RUN_NAMES``):
    its continuous parameters but the static ones (``static_parameters``) and those its run does not
    read (``jaxmpm.calibrate.unused``: varying them, every member would run the same).

    Args:
        scene: a scene or a scene class.

    Returns:
        The names, in the scene's order.
    """
    skip = {*static_parameters(scene), *unused(scene), "dt"}
    return tuple(n for n in continuous_parameters(scene) if n not in skip)


RUN_NAMES = ("dt", "t_end", "cfl")
"""The run's own continuous inputs that ``vary`` may name besides the scene's parameters."""

TO_END_NAMES = ("t_end", "cfl")
"""The inputs of ``RUN_NAMES`` that belong to a run to an end time (``dt`` to a run of fixed steps)."""


@eqx.filter_jit
def _run_batch(model, dt, batch: dict, steps: int, saveat, block):
    """Every member of ``batch`` in one compiled, vmap-ed call (compiled once per structure)."""

    def one(values):
        scene_vals = {k: v for k, v in values.items() if k not in RUN_NAMES}
        m = eqx.tree_at(lambda md: md.scene, model, _with(model.scene, scene_vals)) if scene_vals else model
        d = dt
        if "dt" in values:
            d = values["dt"]
        elif "t_end" in values or "cfl" in values:
            d = eqx.tree_at(
                lambda z: (z.t_end, z.cfl), dt, (values.get("t_end", dt.t_end), values.get("cfl", dt.cfl))
            )
        return run_scan(m, d, steps, saveat, block)

    return jax.vmap(one)(batch)


def _with(scene: AbstractScene, values: dict) -> AbstractScene:
    names = tuple(values)
    return eqx.tree_at(lambda s: tuple(getattr(s, n) for n in names), scene, tuple(values[n] for n in names))


def _check_vary_names(scene: AbstractScene, vary: Mapping) -> None:
    """Each name of ``vary`` one that an ensemble can vary: the run's ``RUN_NAMES`` or one of the
    scene's ``variable_parameters``; the others refused by name (the static ones, those the run does
    not read, the structural ones), with the names that can vary."""
    check_scene(scene)
    allowed = variable_parameters(scene)
    can = f"parameters that can vary: {', '.join(allowed + RUN_NAMES)}"
    structural = [k for k, v in type(scene).parameters().items() if not isinstance(v, float)]
    idle = unused(scene)
    for k in vary:
        if k in idle:
            raise ValueError(
                f"vary names {k!r}, which the run does not use: {idle[k]}; every member would run "
                f"the same; {can}"
            )
        if k in RUN_NAMES or k in allowed:
            continue
        if k in static_parameters(scene):
            raise ValueError(
                f"vary names {k!r}, a static parameter of {scene.name}: it places the particles when "
                f"the run is compiled, so one compiled ensemble cannot vary it; run one ensemble per "
                f"value of {k}, set on the scene; {can}"
            )
        if k in structural:
            raise ValueError(
                f"vary names {k!r}, a structural parameter of {scene.name} (fixed when the run is "
                f"compiled); {can}"
            )
        raise ValueError(f"vary names an unknown parameter {k!r} of {scene.name}; {can}")


def _check_ranges(scene: AbstractScene, arrays: dict[str, np.ndarray]) -> None:
    """Each member's values within what its parameters allow: ``dt``, ``t_end`` and ``cfl`` > 0, and
    each member's scene accepted by the scene's own checks (the scene itself with the member's
    values: what it does not vary kept, a ``Bodies`` scene's parts too). With one scene parameter
    varied, its smallest and largest values are checked; with two or more, every distinct member's
    values together (about 1 ms a member), since a check can tie them (``P0 > p_atm``): an extreme
    of one is checked with its own member's other values, never with the base scene's. A refused
    value is named with its member's index."""
    for name, a in arrays.items():
        if name in RUN_NAMES and not np.all(a > 0):
            i = int(np.flatnonzero(~(a > 0))[0])
            raise ValueError(f"vary[{name!r}] must be > 0, got {a[i]:g} (member {i})")
    joint = [name for name in arrays if name not in RUN_NAMES]
    if len(joint) == 1:
        (name,) = joint
        a = arrays[name]
        for i in (int(np.argmin(a)), int(np.argmax(a))):
            try:
                dataclasses.replace(scene, **{name: float(a[i])})
            except ValueError as e:
                refused = (
                    f"vary[{name!r}] holds {a[i]:g}, which {type(scene).__name__} refuses: {e} (member {i})"
                )
                raise ValueError(refused) from None
    if len(joint) < 2:
        return
    rows = np.stack([np.asarray(arrays[name], dtype=float) for name in joint], axis=1)
    _, first = np.unique(rows, axis=0, return_index=True)
    for i in sorted(int(k) for k in first):
        values = {name: float(rows[i, j]) for j, name in enumerate(joint)}
        try:
            dataclasses.replace(scene, **values)
        except ValueError as e:
            given = ", ".join(f"{k}={v:g}" for k, v in values.items())
            refused = f"member {i} of vary ({given}) is refused by {type(scene).__name__}: {e}"
            raise ValueError(refused) from None


def ensemble(
    scene: AbstractScene,
    interpolator: AbstractInterpolator,
    vary: dict,
    *,
    devices=None,
    **simulate_kwargs,
) -> Ensemble:
    """Run one member per row of ``vary`` in one compiled call, with a status per member.

    Args:
        scene: the base scene.
        interpolator: the method.
        vary: a dict of continuous parameter names (the scene's ``variable_parameters``, not its
            static ones such as the shock tube's ``x0``; with fixed steps ``dt``, with ``t_end``:
            ``t_end`` and ``cfl``) to arrays of equal length: one value per member.
        devices: the devices to shard the members over: a sequence of devices, or a count ``k`` (the
            first ``k`` of ``jax.devices()``), as for ``simulate`` (default: every local device).
        **simulate_kwargs: as for ``simulate`` (``dt``, ``steps`` or ``t_end``, ``max_steps``, ...);
            ``throw`` is always ``False``: failures are read from the status.

    Returns:
        An ``Ensemble``.

    Raises:
        ValueError: bad ``vary`` (not a dict, unknown, structural or static names, a name the run
            does not use: ``t_end`` or ``cfl`` with fixed steps, ``dt`` with ``t_end``, a constant
            the scene's run does not read, ``jaxmpm.calibrate.unused``; values that are not
            real numbers, arrays of different lengths, values that are not finite or that the
            parameter does not allow, a member whose values together the scene refuses, named by
            its index), bad run arguments, or more members than the device's memory holds
            (estimated before anything is allocated).
        TypeError: a keyword ``simulate`` does not take (the message lists those it takes).
        KeyboardInterrupt: Ctrl-C while the members ran (``long_run.computed``: at once under the command
            line): nothing is returned.
    """
    check_keywords("ensemble", simulate_kwargs, simulate)
    devices = list(jax.local_devices() if devices is None else as_devices(devices))
    if any_traced((scene, dict(vary) if isinstance(vary, Mapping) else None, simulate_kwargs)):
        raise ValueError(
            "jm.ensemble batches its members itself, in one compiled call: call it outside jax.vmap, "
            "jax.jit and jax.grad, with the values to run in vary= (or jax.vmap over jm.simulate)"
        )
    if not isinstance(vary, Mapping):
        raise ValueError(
            "vary must be a dict of parameter name to values, one per member (such as "
            f"{{'beta': [100.0, 200.0]}}), got {type(vary).__name__} {brief(vary)}"
        )
    if not vary:
        raise ValueError("vary must name at least one parameter with its values per member")
    _check_vary_names(scene, vary)
    to_end = simulate_kwargs.get("t_end") is not None
    for k in vary:
        if k in TO_END_NAMES and not to_end:
            raise ValueError(
                f"vary names {k!r}, which belongs to a run to an end time (t_end=..., cfl=..., "
                "max_steps=...); this run takes fixed steps (dt and steps): vary 'dt' instead, or "
                "run to t_end"
            )
        if k == "dt" and to_end:
            raise ValueError(
                "vary names 'dt', which belongs to a run of fixed steps (dt and steps); this run goes "
                "to t_end, its steps set by cfl: vary 't_end' or 'cfl' instead"
            )
        if k in RUN_NAMES and k not in simulate_kwargs:
            raise ValueError(f"vary names {k!r}, so pass a value for {k} too (it gives the mode and dtype)")
    arrays = {}
    for k, v in vary.items():
        if not is_real(v):
            raise ValueError(
                f"vary[{k!r}] must be a 1D sequence of real numbers, one per member, got {brief(v)}"
            )
        if np.asarray(v).dtype == np.bool_:  # True and False are not parameter values
            raise ValueError(f"vary[{k!r}] must be real numbers, one per member, got bools {brief(v)}")
        arrays[k] = np.asarray(v, dtype=np.float64)
    sizes = {k: a.shape for k, a in arrays.items()}
    if any(a.ndim != 1 for a in arrays.values()) or len(set(sizes.values())) != 1:
        raise ValueError(f"every vary entry must be a 1D array of the same length, got shapes {sizes}")
    n = next(iter(arrays.values())).size
    if n < 1:
        raise ValueError("vary must hold at least one member")
    bad = [k for k, a in arrays.items() if not np.all(np.isfinite(a))]
    if bad:
        raise ValueError(f"vary values must be finite; not finite in {bad}")
    _check_ranges(scene, arrays)
    limit = simulate_kwargs.get("cfl_limit", 1.0)  # (simulate checks it; here only a number's)
    if "cfl" in arrays and is_real(limit) and not isinstance(limit, bool) and np.any(arrays["cfl"] > limit):
        i = int(np.flatnonzero(arrays["cfl"] > limit)[0])
        raise ValueError(
            f"vary['cfl'] is above cfl_limit = {float(limit):g}: {arrays['cfl'][i]:g} (member {i}), every "
            "full step of which would fail its stability check; vary cfl <= cfl_limit (or pass "
            "cfl_limit=None to run without the check)"
        )
    throw = simulate_kwargs.pop("throw", False)
    if throw is not False:
        raise ValueError(
            f"throw must be False or left out in an ensemble (each member's breakdown is read from its "
            f"status, Ensemble.failures()), got {throw!r}"
        )
    model, dt, steps, saveat = prepare(scene, interpolator, **simulate_kwargs)
    _memory.check_run(model, steps, saveat, members=n)  # before the batch is laid out
    block = checkpoint_block(simulate_kwargs.get("checkpoint", False), steps)

    k = len(devices)
    padded = -(-n // k) * k
    dtype = scene.h.dtype
    batch = {
        name: jnp.asarray(np.concatenate([a, np.repeat(a[-1:], padded - n)]), dtype=dtype)
        for name, a in arrays.items()
    }
    if k > 1:
        sharding = NamedSharding(Mesh(np.asarray(devices), ("members",)), PartitionSpec("members"))
        batch = jax.device_put(batch, sharding)

    try:
        sol = computed(_run_batch, model, dt, batch, steps, saveat, block)
    except KeyboardInterrupt:
        raise KeyboardInterrupt(
            f"interrupted while the ensemble's {n} members ran (one compiled call): no member is reported"
        ) from None
    sol = jax.tree_util.tree_map(lambda a: a[:n], sol)
    if not sol.state.status.is_fully_addressable:
        # Several processes: each holds its own members' states; every process gets every member's
        # status, failing step and particle (the rest: multihost_utils.process_allgather).
        where = lambda z: (z.state.status, z.state.fail_step, z.state.fail_particle)  # noqa: E731
        gathered = multihost_utils.process_allgather(where(sol), tiled=True)
        sol = eqx.tree_at(where, sol, tuple(jnp.asarray(a) for a in gathered))
    return Ensemble(
        params={name: a for name, a in arrays.items()},
        solution=sol,
        status=np.asarray(sol.state.status),
        devices=k,
    )
