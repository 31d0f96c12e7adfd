"""One explicit MPM step, assembled from a scene, an interpolator and a transfer.

The step is update-stress-last (USL) as in Sulsky, Chen & Schreyer 1994 and Bonifasi-Lista, Brannon
& Wiskin 2013: (1) particle to grid, ``m_i = sum_p phi_ip m_p`` and ``m_i v_i = sum_p phi_ip m_p
v_p``; (2) forces, ``f_i = -sum_p dphi_ip sigma_p V_p + sum_p phi_ip m_p b_p`` plus the tractions at
the material boundary points; (3) grid update, ``a_i = f_i / m_i``, ``v_i^{n+1} = v_i + dt a_i``
with the velocity boundary conditions; (4) particles, ``x_p += dt sum_i phi_ip v_i^{n+1}`` and the
transfer's velocity update; (5) kinematics, the interpolator's update of ``F``; (6) stress,
``sigma_p = sigma(F_p)``. MUSL (Sulsky, Zhou & Schreyer 1995) re-projects the new particle momenta
to the grid before (4)'s position update.

Optional physics enters by Python structure while tracing (``if scene.body_force is not None``),
so the compiled step holds only what the scene and the run declared.
"""

import dataclasses
import functools
import math
import operator
import weakref
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from . import status as st_bits
from ._checks import (
    brief,
    check_int,
    check_nonnegative,
    check_positive,
    check_scalar,
    is_concrete,
    is_real,
    python_int,
)
from ._util import as_float, contract, det, materialise
from .boundaries import ArtificialLayer, TractionPoints, artificial_layer, fixed_mask, traction_points
from .explosives import ProgrammedBurn
from .grid import Grid
from .interpolators import INTERPOLATORS, AbstractInterpolator
from .interpolators._transfer import any_axis, gradient_forces, points_stencil, shared_corner_forces
from .materials import AbstractEOS, AbstractMaterial, ElasticPlastic
from .particles import Body, State
from .regions import Layout, Region
from .scenes import SCENES, AbstractScene
from .transfers import TRANSFERS, AbstractTransfer
from .viscosity import ArtificialViscosity

ORDERINGS = ("usl", "musl")

VOLUME_AVERAGES = ("cell", "node")
"""The volume-averaged kinematics a run may take (``Model.volume_average``)."""

PRODUCTS_TENSION_BOUND = 1e-3
"""A burnt particle whose products' pressure is below ``-PRODUCTS_TENSION_BOUND rho0 D^2`` (about
``-4e-3 p_CJ`` for gamma = 3) is a breakdown (``status.PRODUCTS_TENSION``): detonation products hold no
tension, so such a pressure means the products' EOS was taken outside its range."""


def _static_float(value):
    """A concrete real number (a NumPy scalar or a 0-d array too) as a Python ``float`` (a static
    field); ``None``, a bool and anything else unchanged, for ``Model``'s checks to name."""
    if (
        value is None
        or isinstance(value, (bool, np.bool_))
        or not is_concrete(value)
        or not is_real(value)
        or np.ndim(value) != 0
    ):
        return value
    return float(value)


def check_parts(scene, interpolator, transfer, viscosity) -> None:
    """Check what a run is made of (``simulate`` and ``Model`` both refuse these before tracing).

    Args:
        scene: must be a jaxmpm scene.
        interpolator: must be a jaxmpm interpolator (``INTERPOLATORS``).
        transfer: must be a jaxmpm transfer (``TRANSFERS``).
        viscosity: must be ``None`` or an ``ArtificialViscosity``.

    Raises:
        ValueError: one of them is not what it must be (checked in the order viscosity, scene,
            interpolator, transfer); a class given for an object is told to call it
            (``jm.GasExpansion()``), a scene's registry name the call that makes it
            (``check_scene``).
    """
    if viscosity is not None and not isinstance(viscosity, ArtificialViscosity):
        raise ValueError(
            f"viscosity must be None or an ArtificialViscosity, got "
            f"{brief(viscosity)}{_class_hint(viscosity, ArtificialViscosity)}"
        )
    check_scene(scene)
    check_interpolator(interpolator)
    if not isinstance(transfer, AbstractTransfer):
        raise ValueError(
            f"transfer must be a jaxmpm transfer (TRANSFERS: {', '.join(TRANSFERS)}), got "
            f"{brief(transfer)}{_object_hint(transfer, TRANSFERS, AbstractTransfer)}"
        )


def check_scene(scene, what: str = "scene") -> None:
    """Check that ``scene`` is a jaxmpm scene object (not its class, not a registry name).

    Args:
        scene: the value given.
        what: the parameter's name, for the message.

    Raises:
        ValueError: ``scene`` is not an ``AbstractScene``; a scene class is told to call it
            (``jm.GasExpansion()``), a registry name the call that makes the scene
            (``jm.SCENES['gas-expansion']()``).
    """
    if isinstance(scene, AbstractScene):
        return
    if isinstance(scene, type) and issubclass(scene, AbstractScene):
        raise ValueError(
            f"{what} must be a jaxmpm scene object, got the class {scene.__name__}: call it, "
            f"{_spelled(scene)}() (with its parameters)"
        )
    if isinstance(scene, str) and scene in SCENES:
        raise ValueError(
            f"{what} must be a jaxmpm scene object, got the name {scene!r}: "
            f"jm.SCENES[{scene!r}]() makes that scene"
        )
    raise ValueError(
        f"{what} must be a jaxmpm scene object such as jm.GasExpansion() (SCENES: {', '.join(SCENES)}), "
        f"got {brief(scene)}"
    )


def _spelled(cls: type) -> str:
    """How a user writes the class ``cls``: ``jm.GasExpansion`` where jaxmpm exports it under that
    name, else its module path."""
    import jaxmpm  # at call time: jaxmpm imports this module

    if getattr(jaxmpm, cls.__name__, None) is cls:
        return f"jm.{cls.__name__}"
    return f"{cls.__module__}.{cls.__name__}"


def _class_hint(value, base: type) -> str:
    """``": it is the class, call it: jm.SPQ()"`` for a subclass of ``base`` given where an object
    is needed ("" for anything else)."""
    if isinstance(value, type) and issubclass(value, base):
        return f": it is the class, call it: {_spelled(value)}()"
    return ""


def _object_hint(value, registry: dict, base: type) -> str:
    """``": pass jm.MPQ()"`` for a name of ``registry`` and ``_class_hint``'s hint for a subclass of
    ``base``, given where the object is needed ("" for anything else)."""
    if isinstance(value, str) and value in registry:
        return f": pass {_made_by(registry[value])}"
    return _class_hint(value, base)


def check_interpolator(interpolator) -> None:
    """Check that ``interpolator`` is a jaxmpm interpolator (an object, not its class nor a registry
    name).

    Args:
        interpolator: the value given.

    Raises:
        ValueError: it is not an ``AbstractInterpolator``; a registry name such as ``"mpq"`` or a
            class such as ``jm.MPQ`` is told the object to pass (``jm.MPQ()``).
    """
    if isinstance(interpolator, AbstractInterpolator):
        return
    raise ValueError(
        "interpolator must be a jaxmpm interpolator such as jm.CPDI() "
        f"(INTERPOLATORS: {', '.join(INTERPOLATORS)}), got {brief(interpolator)}"
        f"{_object_hint(interpolator, INTERPOLATORS, AbstractInterpolator)}"
    )


def _made_by(make) -> str:
    """How a user writes the interpolator or transfer a registry entry makes: ``jm.MPQ()``,
    ``jm.GIMP(contiguous=True)``, ``jm.FLIP()``."""
    if isinstance(make, functools.partial):
        options = ", ".join(f"{k}={v!r}" for k, v in make.keywords.items())
        return f"jm.{make.func.__name__}({options})"
    return f"jm.{make.__name__}()"


def check_cfl_limit(cfl_limit) -> None:
    """Check a run's ``cfl_limit``: ``None``, or one number > 0 (a tracer passes).

    Args:
        cfl_limit: the value given.

    Raises:
        ValueError: ``cfl_limit`` is not ``None`` and not one finite number > 0.
    """
    if cfl_limit is not None:
        check_positive("cfl_limit", cfl_limit)
        check_scalar("cfl_limit", cfl_limit)


def check_dt(dt, batch: str = "") -> None:
    """Check a fixed time step: one finite number > 0 (a tracer passes).

    Args:
        dt: the value given.
        batch: appended to the message of a ``dt`` with a shape (how to run several values instead).

    Raises:
        ValueError: ``dt`` is not a real number, not finite, not > 0, or has a shape.
    """
    if isinstance(dt, bool | np.bool_):  # a bool is a number to NumPy (True: 1.0), not a time step
        raise ValueError(f"dt must be one number > 0 (the time step), got {dt!r}")
    check_positive("dt", dt)
    check_scalar("dt", dt, batch)


def check_model(model) -> None:
    """Refuse what is not a ``Model`` (a scene given in its place, say), naming what is wanted.

    Raises:
        ValueError: ``model`` is not a ``Model``.
    """
    if not isinstance(model, Model):
        if isinstance(model, AbstractScene):
            got = f"the scene {type(model).__name__}: wrap it, jm.Model(scene, interpolator, transfer)"
        else:
            got = type(model).__name__ if isinstance(model, eqx.Module) else brief(model)
        raise ValueError(f"model must be a jm.Model(scene, interpolator, transfer), got {got}")


class Model(eqx.Module):
    """Everything a run is made of: the scene (with its parameters) and the method choices.

    Attributes:
        scene: the scene; its array fields are the differentiable parameters.
        interpolator: how particles query the grid (one of ``INTERPOLATORS``).
        transfer: FLIP, PIC or APIC.
        artificial_cells: layers of artificial cells at each free end (0: none; static).
        cfl_limit: a step with ``dt > cfl_limit h / max(c + |v|)`` is a failure; ``None`` disables
            the check (static).
        viscosity: an ``ArtificialViscosity`` added to the stress in compression, or ``None``.
        ordering: ``"usl"`` (the reference ordering) or ``"musl"`` (static). MUSL (Sulsky, Zhou &
            Schreyer 1995) re-projects the particles' new momenta to the grid after the particle
            velocity update and advances positions, corners, traction points and F with those
            nodal velocities. USL advances them with ``v_i + a_i dt``, which is unbounded where a
            node has just received a tiny mass but a finite force (a particle entering a new cell
            next to a traction or, for SPQ, any internal force through ``S_i'``).
        volume_average: ``None`` (default), ``"cell"`` or ``"node"`` (static): volume-averaged
            kinematics (J-bar). Before the stress, each particle's ``J = det F`` is replaced by a
            local average ``J_bar``, and the stress is evaluated at ``F_bar = (J_bar / J)^(1/dim) F``
            (the F-bar of de Souza Neto et al. 1996; for a gas, whose stress depends on ``J`` alone,
            the pressure at ``J_bar``). ``"cell"`` averages over the particles whose centre lies in
            the same grid cell, ``J_bar = sum V0 J / sum V0`` (a cell-wise constant field);
            ``"node"`` projects ``J`` onto the nodes with the particles' weights, ``J_i = sum_p
            w_ip V0_p J_p / sum_p w_ip V0_p``, and interpolates it back, ``J_bar_p = sum_i w_ip J_i``
            (a continuous, piecewise linear field for linear shape functions). The state's ``F``
            itself is not averaged; an energy equation takes the work of the averaged volume
            change, both ``J`` of the step averaged with the same weights. A scene whose regions
            are of different materials is refused (the average would mix their volume changes).
        devices: ``None`` (default: one device), or the devices one run is spread over (static): the
            particles are sharded over a 1D mesh of them (``jax.sharding``), the grid is replicated.
            Each device scatters its own particles to the grid, the partial grid sums are added
            across the devices (an all-reduce), every device updates the whole grid, and each
            gathers for its own particles. The run adds inert copies of the last particle, so that
            each device holds the same number, a multiple of 8 (``pad_particles``), and drops them
            from what it returns. The result equals the one-device run up to the order of
            the grid sums (round-off; ``shard_particles``).

    Raises:
        ValueError: an argument ``simulate`` would refuse, with its message (``check_parts``,
            ``artificial_cells`` an integer >= 0 and below ``scene.pad``, ``cfl_limit`` None or one
            number > 0), an unknown ``ordering`` or ``volume_average``, or ``devices`` that are not
            distinct devices.
    """

    scene: AbstractScene
    interpolator: AbstractInterpolator
    transfer: AbstractTransfer
    artificial_cells: int = eqx.field(static=True, default=0, converter=python_int)
    cfl_limit: float | None = eqx.field(static=True, default=1.0, converter=_static_float)
    ordering: str = eqx.field(static=True, default="usl")
    viscosity: ArtificialViscosity | None = None
    volume_average: str | None = eqx.field(static=True, default=None)
    devices: tuple[jax.Device, ...] | None = eqx.field(static=True, default=None)

    def __check_init__(self):
        # the checks simulate makes of the same arguments, with the same messages
        check_parts(self.scene, self.interpolator, self.transfer, self.viscosity)
        check_int("artificial_cells", self.artificial_cells, 0)
        if self.artificial_cells > 0 and "free" not in (self.scene.left, self.scene.right):
            raise ValueError(
                f"artificial_cells adds cells outside the body's free faces, and {type(self.scene).__name__} "
                f"has none (left={self.scene.left!r}, right={self.scene.right!r}): use artificial_cells=0"
            )
        if self.artificial_cells > 0 and self.artificial_cells + 1 > self.scene.pad:
            raise ValueError(
                f"pad must be > artificial_cells so the artificial layer stays on the grid; "
                f"got pad={self.scene.pad}, artificial_cells={self.artificial_cells}"
            )
        check_cfl_limit(self.cfl_limit)
        if self.devices is not None:  # (simulate takes a count; a Model holds the devices)
            check_devices(self.devices, count=False)
            _check_every_process(self.devices)
        if self.ordering not in ORDERINGS:
            raise ValueError(f"ordering must be one of {ORDERINGS}, got {self.ordering!r}")
        if self.volume_average is not None and self.volume_average not in VOLUME_AVERAGES:
            raise ValueError(
                f"volume_average must be None or one of {', '.join(map(repr, VOLUME_AVERAGES))}, got "
                f"{self.volume_average!r}"
            )
        if self.volume_average is not None:
            _check_one_material(self.scene)
        check_float_type(self.scene, self.viscosity)


def _check_every_process(devices: tuple[jax.Device, ...]) -> None:
    """Refuse devices that leave out a process when several run this program: each process calls
    the run and takes part in it (a process without a device in it failed to read the result)."""
    count = jax.process_count()
    of = sorted({d.process_index for d in devices})
    if count > 1 and len(of) < count:
        raise ValueError(
            f"devices must include devices of every process when several run ({count} processes; "
            f"these are of process {', '.join(map(str, of))} only): pass devices=len(jax.devices()) "
            "or jax.devices()"
        )


def _check_one_material(scene: AbstractScene) -> None:
    """Refuse volume averaging on regions of different materials: ``J_bar`` averages over the
    particles of a cell or node whatever their region, and would give a stiff material the volume
    change of a soft neighbour (a gas against copper broke down at once)."""
    if scene.regions is None:
        return
    materials = [r.material for r in scene.regions()]
    first = materials[0]
    for k, m in enumerate(materials[1:], start=1):
        same_type = type(m) is type(first) and jax.tree.structure(m) == jax.tree.structure(first)
        if same_type:
            pairs = list(zip(jax.tree.leaves(first), jax.tree.leaves(m)))
            traced = [(a, b) for a, b in pairs if a is not b and not (is_concrete(a) and is_concrete(b))]
            if traced:  # under jax.grad or jax.jit: a traced constant is told equal only by identity
                raise ValueError(
                    f"volume_average averages J over the particles of a cell or node, whatever their "
                    f"region, so every region must be of one material; region {k} of "
                    f"{type(scene).__name__} has traced constants (jax.grad, jax.jit, jax.vmap) that "
                    "are not those of region 0, and traced values cannot be compared: give every region "
                    "the same material object"
                )
        equal = same_type and all(a is b or np.array_equal(np.asarray(a), np.asarray(b)) for a, b in pairs)
        if not equal:
            other = type(m).__name__ + ("" if not same_type else " with other constants")
            raise ValueError(
                f"volume_average averages J over the particles of a cell or node, whatever their region, "
                f"and region {k} of {type(scene).__name__} is of another material ({other}) "
                f"than region 0 ({type(first).__name__}): it would mix their volume changes; run without "
                "volume_average"
            )


def check_float_type(scene: AbstractScene, viscosity: ArtificialViscosity | None = None) -> None:
    """Refuse a scene or viscosity whose parameters are of another float type than the run's: one
    made while float64 was off (float32 arrays) and run after ``jax_enable_x64`` was switched on.

    Args:
        scene: the run's scene.
        viscosity: the run's artificial viscosity, or ``None``.

    Raises:
        ValueError: a float parameter of the scene (its materials' too) or of the viscosity is not
            of the default float type, naming it and what to do.
    """
    want = jnp.result_type(float)
    for what, module in (("scene", scene), ("viscosity", viscosity)):
        for path, leaf in jax.tree_util.tree_leaves_with_path(eqx.filter(module, eqx.is_array)):
            dtype = getattr(leaf, "dtype", None)
            if dtype is not None and jnp.issubdtype(dtype, jnp.floating) and dtype != want:
                name = jax.tree_util.keystr(path).lstrip(".")
                raise ValueError(
                    f"the {what}'s {name} is {dtype} and this run is {want} (jax_enable_x64 is "
                    f"{'on' if want == jnp.float64 else 'off'}): make the {what} after switching float64 "
                    f"on or off, jax.config.update('jax_enable_x64', ...), not before"
                )


class Setup(eqx.Module):
    """What a run derives from its model once, before the time loop.

    Attributes:
        grid: the background grid.
        body: the reference configuration of the real particles.
        material: the scene's material (of a scene of regions: its first region's).
        regions: the scene's regions, or ``None`` for a body of one region.
        layout: which particles belong to which region (static), or ``None``.
        layer: the artificial particles, or ``None``.
        walls: the nodal velocity components held at zero (walls, symmetry planes), or ``None``.
        traction: the material boundary points that carry a traction, or ``None``.
        tiny: node masses at or below this are round-off, not mass (see ``step``).
    """

    grid: Grid
    body: Body
    material: AbstractMaterial | AbstractEOS
    regions: tuple[Region, ...] | None
    layout: Layout | None = eqx.field(static=True)
    layer: ArtificialLayer | None
    walls: Bool[Array, "n_nodes dim"] | None
    traction: TractionPoints | None
    tiny: Float[Array, ""]


def check_devices(devices, count: bool = True) -> tuple[jax.Device, ...]:
    """``devices`` as a tuple of distinct JAX devices, or a ``ValueError`` naming what is allowed
    (``count``: the caller takes a device count too, and the message offers it)."""
    allowed = "a non-empty sequence of distinct JAX devices (e.g. jax.devices())"
    if count:
        allowed += " or a device count"
    if isinstance(devices, str):  # a sequence of letters, not of devices
        raise ValueError(f"devices must be {allowed}, got the string {devices!r}")
    try:
        devices = tuple(devices)
    except TypeError:
        raise ValueError(f"devices must be {allowed}, got {devices!r}") from None
    if not devices or not all(isinstance(d, jax.Device) for d in devices):
        raise ValueError(f"devices must be {allowed}, got {devices!r}")
    if len(set(devices)) != len(devices):
        raise ValueError(f"devices must be distinct, got {devices!r}")
    return devices


def shard_particles(model: Model, tree, n: int):
    """``tree`` laid out over ``model.devices``: arrays whose leading axis has length ``n`` (the
    particles) sharded over the devices, every other array replicated; unchanged for one device.
    Where the devices do not divide ``n``, every array is replicated (XLA's own split of such an axis
    gathers every particle's node indices on every device each step); the step's loop runs on the
    particles padded to a multiple (``pad_particles``).

    Only the layout changes, never a value: XLA's partitioner splits the step's work by it, adding
    the partial grid sums across the devices. Those sums are added in another order than on one
    device, so results agree to round-off (a few ulps a step in float64).

    Args:
        model: the run (``model.devices``).
        tree: a ``State``, a ``Body`` or any pytree of arrays.
        n: the number of particles.

    Returns:
        ``tree``, with sharding constraints on its arrays.
    """
    if model.devices is None:
        return tree
    mesh = jax.sharding.Mesh(np.asarray(model.devices, dtype=object), ("particles",))
    spread = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("particles"))
    whole = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec())
    split = n % len(model.devices) == 0

    def lay(a):
        return jax.lax.with_sharding_constraint(a, spread if split and a.ndim and a.shape[0] == n else whole)

    return jax.tree.map(lay, tree)


_PARTICLE_FIELDS = ("x", "v", "F", "sigma", "C", "e", "internal")
"""The fields of a ``State`` that hold one row per particle."""


PAD_SHARE = 8
"""A run's time loop holds a multiple of this many particles on each of its devices. XLA's CPU loops
run slower over an odd count: 70 steps of 1D SPQ in float64 took 0.73-0.78 s for 500,001 particles
on one device against 0.55-0.61 s for 500,000, 500,002 or 500,004, and over 2 forced host devices
1.07-1.14 s with 250,001 or 250,003 particles a device against 0.84-0.94 s with 250,004 or 250,008
(the performance docs, ``experiments/uneven_shards.py``)."""


def pad_particles(model: Model, setup: Setup, state: State) -> tuple[Setup, State]:
    """The body and state with inert particles added, so that each of the run's devices (one, or each
    of ``model.devices``) holds the same number, a multiple of ``PAD_SHARE``.

    Each added particle is a copy of the last one (position, domain, corners, deformation, stress,
    velocity, energy, internal variables) with zero mass and zero volume: it gives the grid no mass,
    momentum or force (it adds exact zeros to the grid's sums, so with fixed steps the real
    particles' results are bit for bit those of the run without it; with CFL steps XLA may round
    the padded program's step otherwise, by an ulp), and it moves and deforms exactly as the
    particle it copies, so it fails no check before that one (a failure names the lowest index, a
    real particle's). Its stress, energy and internal variables are then its material's for that
    motion, or zero in a body of several regions, whose materials update their own particles only;
    both pass every check. The drivers pad before the time loop and drop the copies after it
    (``unpad_particles``); ``step`` takes the particles as they are. The padded body records the
    copies (``Body.inert``): its 1D corners are no chain, and the CFL step leaves them out of its
    maximum.

    Args:
        model: the run (``model.devices``).
        setup: ``setup(model)``.
        state: a state of ``model``'s particles.

    Returns:
        ``(setup, state)``, unchanged where the particles split so already.
    """
    n = setup.body.n
    extra = -n % (PAD_SHARE * (1 if model.devices is None else len(model.devices)))
    if not extra:
        return setup, state

    def copies(a):
        return jnp.concatenate([a, jnp.broadcast_to(a[-1:], (extra,) + a.shape[1:])])

    def zeros(a):
        return jnp.concatenate([a, jnp.zeros((extra,) + a.shape[1:], a.dtype)])

    b = setup.body
    body = dataclasses.replace(  # the corners (X_corners) stay: the copies share the last one's
        b,
        X=copies(b.X),
        r0=copies(b.r0),
        m=zeros(b.m),
        V0=zeros(b.V0),
        corner_ids=copies(b.corner_ids),
        boundary=copies(b.boundary),
        region=None if b.region is None else copies(b.region),
        inert=b.inert + extra,
    )
    fields = {name: jax.tree.map(copies, getattr(state, name)) for name in _PARTICLE_FIELDS}
    return eqx.tree_at(lambda z: z.body, setup, body), dataclasses.replace(state, **fields)


def unpad_particles(state: State, n: int) -> State:
    """``state`` without the particles ``pad_particles`` added: its first ``n`` (unchanged if it has
    ``n``).

    Args:
        state: a state of the padded particles.
        n: the number of real particles.

    Returns:
        The state of the real particles.
    """
    if state.x.shape[0] == n:
        return state
    fields = {name: jax.tree.map(lambda a: a[:n], getattr(state, name)) for name in _PARTICLE_FIELDS}
    return dataclasses.replace(state, **fields)


def place_particles(model: Model, tree, n: int):
    """Host arrays put on ``model.devices`` laid out as ``shard_particles`` lays them out (with
    several processes, each process places its own part).

    Args:
        model: the run (``model.devices`` not ``None``).
        tree: a pytree of NumPy arrays, the same on every process.
        n: the number of particles.

    Returns:
        ``tree`` as JAX arrays on the devices.
    """
    mesh = jax.sharding.Mesh(np.asarray(model.devices, dtype=object), ("particles",))
    split = n % len(model.devices) == 0

    def put(a):
        spec = (
            jax.sharding.PartitionSpec("particles")
            if split and a.ndim and a.shape[0] == n
            else jax.sharding.PartitionSpec()
        )
        return jax.make_array_from_callback(a.shape, jax.sharding.NamedSharding(mesh, spec), lambda i: a[i])

    return jax.tree.map(put, tree)


def _faces(scene: AbstractScene, t):
    """``scene.traction(t)``, one function for every scene: through ``_FACES`` its shape is traced
    once per scene structure, not again for new parameter values."""
    return scene.traction(t)


_FACES = jax.jit(_faces)


def traction_sides(scene: AbstractScene) -> tuple[bool, ...]:
    """Which faces carry a traction, read from the structure of ``scene.traction``.

    Args:
        scene: the scene.

    Returns:
        One bool per face: low and high face of axis 0, then of axis 1, ...

    Raises:
        ValueError: ``scene.traction`` gives the wrong number of faces.
    """
    dim = scene.dim
    if scene.traction is None:
        return (False,) * (2 * dim)
    t = jax.ShapeDtypeStruct((), scene.h.dtype)
    try:
        faces = _FACES.eval_shape(scene, t)
    except TypeError:  # a leaf that is not an array (a scene of the user's): traced at every call
        faces = jax.eval_shape(scene.traction, t)
    if len(faces) != 2 * dim:
        raise ValueError(
            f"{type(scene).__name__}.traction must return {2 * dim} entries (low and high face of each "
            f"of {dim} axes), got {len(faces)}"
        )
    return tuple(f is not None for f in faces)


def check_structure(scene: AbstractScene, artificial_cells: int) -> None:
    """What a scene's regions allow (``simulate`` checks it before anything is traced).

    Args:
        scene: the scene.
        artificial_cells: layers of artificial cells of the run.

    Raises:
        ValueError: a parameter of another float type than the run's (``check_float_type``), a
            traction on a wall (which holds its nodes at rest, so the load would be lost), a
            one-region scene with an energy equation, or artificial cells or a traction on a body of
            regions that does not fill its box.
    """
    check_float_type(scene)  # before the traction is traced: a float32 field would fail in it
    for k, loaded in enumerate(traction_sides(scene)):
        if loaded and (scene.left, scene.right)[k % 2] == "wall":
            raise ValueError(
                f"{type(scene).__name__}.traction loads the {('low', 'high')[k % 2]} face of axis "
                f"{k // 2}, which is a wall: a wall holds its nodes at rest, so the load would be lost "
                f"(make that face free or a symmetry plane, or leave its entry None)"
            )
    lay = scene.layout()
    if lay is not None:
        _check_detonators(scene)
    if lay is None:
        if isinstance(scene.material(), AbstractEOS):
            raise ValueError(
                f"{type(scene).__name__}: a material with an energy equation "
                f"({type(scene.material()).__name__}) needs the scene's regions (each with its initial "
                f"energy); declare regions"
            )
        return
    if lay.box:
        return
    if artificial_cells > 0:
        raise ValueError(
            f"artificial_cells is supported only where the body is a box; the regions of "
            f"{type(scene).__name__} do not fill [0, cells]^dim (use artificial_cells=0)"
        )
    if scene.traction is not None:
        raise ValueError(
            f"a traction is supported only on the faces of a box; the regions of {type(scene).__name__} do "
            f"not fill [0, cells]^dim (curved and inner boundaries are free surfaces of zero traction)"
        )


def _check_detonators(scene: AbstractScene) -> None:
    """A programmed burn's detonator points, and the given point of each line detonator, lie in the scene's
    box ``[0, cells h]^dim`` (checked where concrete)."""
    for k, region in enumerate(scene.regions()):
        burn = region.material
        if not isinstance(burn, ProgrammedBurn) or not is_concrete(burn.points) or not is_concrete(scene.h):
            continue
        points, top = np.asarray(burn.points), float(scene.cells * scene.h)
        if points.shape[1] != scene.dim:
            raise ValueError(
                f"region {k}: its ProgrammedBurn's detonators are {points.shape[1]}D points, the scene is "
                f"{scene.dim}D"
            )
        anchors = [("points", points)]
        if burn.lines is not None and is_concrete(burn.lines):
            anchors.append(("lines", np.asarray(burn.lines)[:, : scene.dim]))  # a line's point a
        for name, at in anchors:
            outside = np.any((at < 0.0) | (at > top), axis=1)
            if outside.any():
                i = int(np.argmax(outside))
                raise ValueError(
                    f"region {k}: a detonator of its ProgrammedBurn lies outside the body's box [0, {top:g}]^"
                    f"{scene.dim}: {name}[{i}] = {at[i].tolist()}"
                )


class _Group(NamedTuple):
    """The particles of one material: the material, its reference density and which particles (a
    slice, static indices, or ``None`` for all)."""

    material: AbstractMaterial | AbstractEOS
    rho0: Float[Array, ""]
    index: slice | np.ndarray | None


def _groups(model: Model, setup: Setup) -> list[_Group]:
    if setup.regions is None:
        return [_Group(setup.material, model.scene.rho0, None)]
    return [_Group(r.material, r.rho0, setup.layout.index(k)) for k, r in enumerate(setup.regions)]


def _take(a, index):
    return a if index is None else a[index]


def _assemble(parts, groups, n):
    """One array from each group's part (a single group's part is the whole)."""
    if groups[0].index is None:
        return parts[0]
    out = jnp.zeros((n,) + parts[0].shape[1:], dtype=parts[0].dtype)
    for part, g in zip(parts, groups):
        out = out.at[g.index].set(part)
    return out


def _internal_keys(material, dim: int, dtype) -> tuple[str, ...]:
    if not isinstance(material, AbstractEOS):
        return ()
    z = jax.eval_shape(material.initial_internal, jax.ShapeDtypeStruct((dim,), dtype))
    return () if z is None else tuple(sorted(z))


def _subset(internal, keys, index):
    return None if not keys else {k: _take(internal[k], index) for k in keys}


def _eos_stress(p, dim, dtype):
    return -p[:, None, None] * jnp.eye(dim, dtype=dtype)[None]


def setup(model: Model) -> Setup:
    """Derive what the run needs once: grid, body, material, artificial layer, walls, traction points.

    Args:
        model: the run.

    Returns:
        The ``Setup``.

    Raises:
        ValueError: ``model`` is not a ``Model``, or the scene's traction has the wrong number of
            faces.
    """
    check_model(model)
    scene = model.scene
    grid = scene.grid()
    free = (scene.left == "free", scene.right == "free")
    walls = fixed_mask(grid.axes, scene.pad, scene.cells, scene.left, scene.right)
    check_structure(scene, model.artificial_cells)
    lay = scene.layout()
    body = scene.body()
    return Setup(
        grid=grid,
        body=body,
        material=scene.material(),
        regions=None if lay is None else scene.regions(),
        layout=lay,
        layer=artificial_layer(scene.cells, scene.ppc, model.artificial_cells, free, scene.dim),
        walls=None if walls is None else jnp.asarray(walls),
        traction=traction_points(scene.cells, scene.ppc, scene.h, traction_sides(scene)),
        tiny=256 * jnp.finfo(body.m.dtype).eps * jnp.max(body.m),
    )


def initial_state(model: Model, setup: Setup) -> State:
    """The state at ``t = 0``.

    Particles sit at their reference positions with ``F = I``, or where ``scene.initial_position``
    puts them with ``F = dx/dX``; velocities are ``scene.initial_velocity``.

    Args:
        model: the run.
        setup: what it derives once (``setup(model)``).

    Returns:
        The ``State``.

    Raises:
        ValueError: ``setup`` is not a ``Setup`` of ``model`` as far as its shapes tell (another
            run's: another particle count, dimension or grid; ``check_belongs``).
    """
    check_model(model)
    check_belongs(model, setup)
    return start_state(model, setup)


def start_state(model: Model, setup: Setup) -> State:
    """``initial_state`` without the check that ``setup`` belongs to ``model`` (the drivers', which
    derive ``setup`` from ``model`` themselves, also inside a trace).

    Args:
        model: the run.
        setup: ``setup(model)``.

    Returns:
        The ``State`` at ``t = 0``.
    """
    scene, body = model.scene, setup.body
    n, dim = body.X.shape
    dtype = body.X.dtype
    x_tr = None if setup.traction is None else setup.traction.X
    if scene.initial_position is None:
        x, corners = body.X, body.X_corners
        F = jnp.broadcast_to(jnp.eye(dim, dtype=dtype), (n, dim, dim))
    else:  # a body that starts deformed: F = dx/dX, corners and traction points mapped alike
        place = jax.vmap(scene.initial_position)
        x, corners = place(body.X), place(body.X_corners)
        F = jax.vmap(jax.jacfwd(scene.initial_position))(body.X)
        x_tr = None if x_tr is None else place(x_tr)
    corners = corners if model.interpolator.tracks_corners else None
    e = internal = None
    if setup.regions is None:
        v = jax.vmap(scene.initial_velocity)(body.X)
        C = jax.vmap(jax.jacfwd(scene.initial_velocity))(body.X) if model.transfer.affine else None
        if model.transfer.affine and scene.initial_position is not None:
            C = jnp.einsum("nab,nbc->nac", C, jnp.linalg.inv(F))  # C = dv/dx = dv/dX F^-1
        sigma = jax.vmap(setup.material.stress)(F)
    else:  # each region's uniform velocity (C = 0), energy, internal variables and stress
        reg = jnp.asarray(setup.layout.region)
        v = jnp.stack([r.velocity.astype(dtype) for r in setup.regions])[reg]
        C = jnp.zeros((n, dim, dim), dtype=dtype) if model.transfer.affine else None
        sigma, e, internal = _initial_regions(model, setup, F)
    # The initial state is checked as every step's is: a body that starts inverted or with a
    # non-finite field (a scene's initial_position or velocity) fails at step 0, and no step is taken.
    finite = _finite_particles(body, x, v, F, sigma, corners, e, internal)
    checks = [(st_bits.NONFINITE, ~finite), (st_bits.NONPOSITIVE_F, det(F) <= 0.0)]
    negative = None if e is None else _negative_energy(model, setup, e)
    if negative is not None:
        checks.append((st_bits.NEGATIVE_ENERGY, negative))
    status, particle = st_bits.combine(checks, sharded=model.devices is not None)
    return State(
        t=jnp.zeros((), dtype=dtype),
        step=jnp.zeros((), dtype=jnp.int32),
        x=x,
        v=v,
        F=F,
        sigma=sigma,
        C=C,
        corners=corners,
        x_traction=x_tr,
        e=e,
        internal=internal,
        status=status,
        fail_step=jnp.where(status != 0, 0, -1).astype(jnp.int32),
        fail_particle=particle,
    )


_EXPECTED: dict = {}
"""Model structure (tree structure, array shapes and dtypes, other leaves) to the shapes of its
``Setup`` and ``State`` (``_expected``), so that a loop of ``step`` derives them once."""

_EXPECTED_MOST = 64

_LAST_CHECKED: list = [None, None, None]
"""Weak references to the last model and setup that ``check_belongs`` passed, and their expected
shapes: a loop of ``step`` with the same two objects checks only its state."""


def _shapes(tree) -> tuple:
    """``tree``'s structure and the shapes of its leaves, for a quick comparison (the structure of a
    ``State``; a ``Setup``'s holds static fields made anew by every ``setup``, so only its shapes)."""
    leaves, treedef = jax.tree.flatten(tree)
    return treedef, tuple(tuple(a.shape) if hasattr(a, "shape") else np.shape(a) for a in leaves)


def _paths(tree) -> dict:
    """``tree``'s leaves as ``keystr`` path (``".body.X"``) to shape."""
    flat = jax.tree_util.tree_flatten_with_path(tree)[0]
    return {jax.tree_util.keystr(p): tuple(a.shape) if hasattr(a, "shape") else np.shape(a) for p, a in flat}


def _model_key(model: Model):
    """What the shapes of ``model``'s setup and state depend on, or ``None`` where it cannot be
    hashed (then they are derived on every call)."""
    leaves, treedef = jax.tree.flatten(model)
    key = (treedef, tuple((a.shape, str(a.dtype)) if eqx.is_array(a) else a for a in leaves))
    try:
        hash(key)
    except TypeError:
        return None
    return key


def _expected(model: Model) -> tuple:
    """``model``'s ``Setup`` and initial ``State`` as shapes (``jax.eval_shape``, nothing computed),
    with their ``_shapes``."""
    key = _model_key(model)
    if key is not None and key in _EXPECTED:
        return _EXPECTED[key]
    abstract = eqx.filter_eval_shape(setup, model)
    state = eqx.filter_eval_shape(start_state, model, abstract)
    out = (abstract, _shapes(abstract), state, _shapes(state))
    if key is not None:
        if len(_EXPECTED) >= _EXPECTED_MOST:
            del _EXPECTED[next(iter(_EXPECTED))]
        _EXPECTED[key] = out
    return out


def _mismatch(name: str, given, given_shapes: tuple, expected, expected_shapes: tuple) -> str | None:
    """The first entry of ``given`` whose shape differs from ``expected``'s, or that one of them
    lacks, in words (``None``: the shapes agree). ``given_shapes`` and ``expected_shapes`` are their
    ``_shapes``; ``name`` starts the entry's path (``"state"``)."""
    if given_shapes[1] == expected_shapes[1]:
        return None
    have, want = _paths(given), _paths(expected)
    for path, shape in want.items():
        if path not in have:
            return f"{name}{path} is None, should have shape {shape}"
        if have[path] != shape:
            return f"{name}{path} has shape {have[path]}, should be {shape}"
    for path, shape in have.items():
        if path not in want:
            return f"{name}{path} has shape {shape}, should be None"
    return None


def _weak(obj):
    try:
        return weakref.ref(obj)
    except TypeError:
        return None


_SETUP_ONLY = object()
"""``check_belongs``'s default ``state``: check the setup alone."""


def check_belongs(model: Model, setup, state=_SETUP_ONLY) -> None:
    """Check, on the host before anything is traced, that ``setup`` (and ``state``) are ``model``'s
    as far as their shapes tell: particle count, dimension, grid nodes, and which optional fields
    (``corners``, ``C``, ``x_traction``, ``e``, ``internal``) the run has. Values are not compared,
    so a tracer passes as any array of its shape.

    Args:
        model: the run.
        setup: the ``Setup`` given with it.
        state: the ``State`` given with it; left out to check ``setup`` alone.

    Raises:
        ValueError: ``setup`` or ``state`` is not a ``Setup`` or ``State``, or is another run's: the
            message names the argument, the first entry that differs and what it should be.
    """
    if not isinstance(setup, Setup):
        raise ValueError(f"setup must be the Setup of model, jm.setup(model), got {brief(setup)}")
    if state is not _SETUP_ONLY and not isinstance(state, State):
        raise ValueError(
            f"state must be a State of model (jm.initial_state(model, setup) or a step's), got {brief(state)}"
        )
    model_ref, setup_ref, expected = _LAST_CHECKED
    known = model_ref is not None and setup_ref is not None and model_ref() is model and setup_ref() is setup
    if not known:
        expected = _expected(model)
    abstract, setup_shapes, initial, state_shapes = expected
    n, dim = abstract.body.X.shape
    run = f"model ({n} particles in {dim}D, {abstract.grid.n_nodes} grid nodes)"
    if not known:
        wrong = _mismatch("setup", setup, _shapes(setup), abstract, setup_shapes)
        grid, want = setup.grid, abstract.grid
        if wrong is None and (grid.n_nodes, grid.shape) != (want.n_nodes, want.shape):
            wrong = (
                f"setup.grid has {grid.n_nodes} nodes (shape {grid.shape}), should have "
                f"{want.n_nodes} (shape {want.shape})"
            )
        if wrong is not None:
            raise ValueError(f"setup does not belong to {run}: {wrong}; make it with jm.setup(model)")
        _LAST_CHECKED[:] = [_weak(model), _weak(setup), expected]
    if state is _SETUP_ONLY:
        return
    given = _shapes(state)
    wrong = _mismatch("state", state, given, initial, state_shapes)
    if wrong is None and given[0] != state_shapes[0]:
        wrong = f"its fields are {_paths(state)}, should be {_paths(initial)}"
    if wrong is not None:
        raise ValueError(
            f"state does not belong to {run}: {wrong}; start from jm.initial_state(model, setup)"
        )


def _initial_regions(model: Model, setup: Setup, F):
    """Stress, energy and internal variables at ``t = 0`` of a body of regions."""
    body = setup.body
    n, dim = body.X.shape
    dtype = body.X.dtype
    groups = _groups(model, setup)
    eos = [isinstance(g.material, AbstractEOS) for g in groups]
    keys = sorted({k for g in groups for k in _internal_keys(g.material, dim, dtype)})
    e = None
    if any(eos):
        e = jnp.stack([r.energy.astype(dtype) for r in setup.regions])[jnp.asarray(setup.layout.region)]
    internal = {k: jnp.zeros((n,), dtype=dtype) for k in keys} or None
    sig = []
    for g, is_eos in zip(groups, eos):
        F_g = _take(F, g.index)
        if not is_eos:
            sig.append(jax.vmap(g.material.stress)(F_g))
            continue
        z = jax.vmap(g.material.initial_internal)(_take(body.X, g.index))
        if z is not None:
            for k, val in z.items():
                internal[k] = internal[k].at[g.index].set(val.astype(dtype))
        rho = g.rho0 / det(F_g)
        p = jax.vmap(g.material.pressure)(rho, _take(e, g.index), z)
        s_g = _eos_stress(p, dim, dtype)
        if isinstance(g.material, ElasticPlastic):
            s_g = s_g + jax.vmap(functools.partial(g.material.stress_of, dim=dim))(z)
        sig.append(s_g)
    return _assemble(sig, groups, n), e, internal


def _particle_corners(state: State, body: Body):
    return None if state.corners is None else body.particle_corners(state.corners)


def _sound_speed(model: Model, setup: Setup, state: State) -> Float[Array, " n"]:
    """Each particle's wave speed; the stored stress stands in for work on ``F`` when it is the
    material's alone (no viscous part). An ``ElasticPlastic`` material's is the longitudinal elastic
    wave's, ``sqrt(c_eos^2 + 4 G / (3 rho))``."""
    groups = _groups(model, setup)
    out = []
    for g in groups:
        F = _take(state.F, g.index)
        if isinstance(g.material, AbstractEOS):
            keys = _internal_keys(g.material, F.shape[-1], F.dtype)
            z = _subset(state.internal, keys, g.index)
            c = jax.vmap(g.material.sound_speed)(g.rho0 / det(F), _take(state.e, g.index), z)
            if isinstance(g.material, ElasticPlastic):  # the longitudinal elastic wave
                c = jnp.sqrt(c * c + 4.0 * g.material.G / (3.0 * (g.rho0 / det(F))))
            front = g.material.front_speed()
            if front is not None:  # a programmed detonation: its front moves at least this fast
                c = jnp.maximum(c, front)
        elif model.viscosity is None:
            fn = jax.vmap(g.material.sound_speed_from_stress, in_axes=(0, 0, None))
            c = fn(F, _take(state.sigma, g.index), g.rho0)
        else:
            c = jax.vmap(g.material.sound_speed, in_axes=(0, None))(F, g.rho0)
        out.append(c)
    return _assemble(out, groups, state.F.shape[0])


def _transfer_to_grid(grid: Grid, transfer: AbstractTransfer, stencil, x, v, C, m):
    """Nodal mass and momentum that particles with ``stencil`` put on the grid (the step's stage 1)."""
    mass = grid.scatter(stencil.idx, stencil.w * m[:, None], stencil.base)
    return mass, grid.scatter(stencil.idx, transfer.momentum(grid, stencil, x, v, C, m), stencil.base)


def particle_to_grid(
    model: Model, setup: Setup, state: State
) -> tuple[Float[Array, " n_nodes"], Float[Array, "n_nodes dim"]]:
    """Nodal mass and momentum of the real particles of ``state``.

    The step's first stage without the artificial particles (for output; the step itself adds them).

    Args:
        model: the run.
        setup: what it derives once.
        state: the state.

    Returns:
        ``(mass, momentum)``.
    """
    corners = _particle_corners(state, setup.body)
    stencil = model.interpolator.stencil(
        setup.grid, setup.body.r0, state.x, state.F, corners, gradients=False
    )
    return _transfer_to_grid(setup.grid, model.transfer, stencil, state.x, state.v, state.C, setup.body.m)


def stable_dt(model: Model, setup: Setup, state: State, cfl: Float[Array, ""]) -> Float[Array, ""]:
    """The CFL-limited step ``cfl h / max_p(c_p + |v_p|)`` of the current state.

    Args:
        model: the run.
        setup: what it derives once.
        state: the state.
        cfl: the Courant number.

    Returns:
        The time step.
    """
    c = _sound_speed(model, setup, state)
    speed = c + _speed(state.v)
    inert = setup.body.inert
    if inert:  # the copies that pad the run tie with the particle they copy: left out of the max,
        # they take no share of its derivative (as the run without them)
        real = jnp.arange(speed.shape[0]) < speed.shape[0] - inert
        speed = jnp.where(real, speed, -jnp.inf)
    return cfl * setup.grid.h / jnp.max(speed)


def step(
    model: Model,
    setup: Setup,
    state: State,
    dt: Float[ArrayLike, ""],
    limit: Int[Array, ""] | None = None,
    active: Bool[Array, ""] | None = None,
    t_new: Float[Array, ""] | None = None,
) -> State:
    """One update-stress-last step (USL, or MUSL with ``model.ordering="musl"``): the particles'
    mass and momentum to the grid, the nodal forces, the grid update with the boundary conditions,
    then the particles' positions and velocities, their ``F`` and their stresses.

    A step that fails a check is not taken: the state stays, its status records it. The step is
    compiled (``equinox.filter_jit``) once per model structure and array shapes, so a Python loop of
    steps runs compiled code; inside the caller's ``jax.jit``, ``grad`` or ``vmap`` it is part of the
    caller's program.

    Args:
        model: the run.
        setup: what it derives once (``setup(model)``).
        state: the state to step from.
        dt: the time step (> 0): a number or a 0-d array, taken as ``simulate`` takes it (as a 0-d
            array of the default float dtype).
        limit: a step from ``state.step >= limit`` is not taken (masking the tail of a fixed-length
            chunk); ``None`` for no limit.
        active: where false, the step is not taken (the tail of a run to an end time); ``None``
            means always active.
        t_new: the time after the step (default ``(step + 1) dt``, for a fixed step).

    Returns:
        The new state, or on failure the old one with its status, failing step and particle set.

    Raises:
        ValueError: a concrete ``dt`` that ``simulate`` would refuse (not one finite number > 0),
            with its message. A traced ``dt`` (inside ``jax.jit``, ``jax.grad``, ``jax.vmap``) is
            not checked. A ``setup`` or ``state`` of another run (``check_belongs``: their shapes
            are compared with ``model``'s, tracers too).
    """
    check_model(model)
    check_dt(dt, ": to step with several values, jax.vmap over step")
    check_belongs(model, setup, state)
    _check_step_options(limit, active, t_new)
    if not isinstance(dt, jax.Array) or dt.dtype != jnp.result_type(float):  # as simulate converts it
        dt = as_float(dt)
    return _compiled_step(model, setup, state, dt, limit, active, t_new)


def _check_step_options(limit, active, t_new) -> None:
    """``step``'s optional arguments, where concrete: ``limit`` one integer, ``active`` one bool,
    ``t_new`` one finite number >= 0 (tracers pass).

    Raises:
        ValueError: one that is not, named.
    """
    if limit is not None and is_concrete(limit):
        if np.ndim(limit) != 0 or not np.issubdtype(np.asarray(limit).dtype, np.integer):
            raise ValueError(f"limit must be one integer (a step count) or None, got {brief(limit)}")
    if active is not None and is_concrete(active):
        if np.ndim(active) != 0 or np.asarray(active).dtype != np.bool_:
            raise ValueError(f"active must be one bool or None, got {brief(active)}")
    if t_new is not None:
        check_scalar("t_new", t_new)
        check_nonnegative("t_new", t_new)


def take_step(
    model: Model,
    setup: Setup,
    state: State,
    dt: Float[Array, ""],
    limit: Int[Array, ""] | None = None,
    active: Bool[Array, ""] | None = None,
    t_new: Float[Array, ""] | None = None,
) -> State:
    """``step`` without the check of ``dt``: the step of the drivers, which check a fixed ``dt``
    once before the loop, or compute it (a run to an end time).

    Args:
        model: the run.
        setup: what it derives once (``setup(model)``).
        state: the state to step from.
        dt: the time step, an array.
        limit: as for ``step``.
        active: as for ``step``.
        t_new: as for ``step``.

    Returns:
        As for ``step``.
    """
    new, bits, particle, healthy = _proposal(model, setup, state, dt, limit, active, t_new)
    ok = healthy & (bits == 0)
    # In 2D and 3D a select, which XLA's CPU backend fuses into the loops that compute the new state
    # (a lax.cond copies the whole state out of its branch every step). In 1D the two take about the
    # same time (the performance docs), and the step uses the cond. Under vmap the cond becomes the
    # select too.
    if setup.grid.dim == 1:
        kept = jax.lax.cond(ok, lambda: new, lambda: state)
    else:
        kept = jax.tree.map(lambda a, b: jnp.where(ok, a, b), new, state)
    first = healthy & (bits != 0)
    return eqx.tree_at(
        lambda z: (z.status, z.fail_step, z.fail_particle),
        kept,
        (
            state.status | jnp.where(healthy, bits, 0),  # a state that failed already keeps its bits
            jnp.where(first, state.step + 1, state.fail_step),
            jnp.where(first, particle, state.fail_particle),
        ),
    )


_compiled_step = eqx.filter_jit(take_step)
"""``take_step`` compiled: the program ``step`` runs (op by op, one step would dispatch hundreds of
small programs, each compiled on first use)."""


@eqx.filter_custom_jvp
def _proposal(model, setup, state, dt, limit, active, t_new):
    """The step proposed from ``state``, its failed checks and their first particle.

    Returns ``(new, bits, particle, healthy)``: the step is taken where ``healthy & (bits == 0)``.
    Its derivative is the step's own where the step is taken, and zero where it is discarded (the
    rule below), so that a discarded step's non-finite values (an inverted particle's ``J^-gamma``)
    do not reach the kept state's reverse-mode derivative as ``0 * NaN``.
    """
    return _propose(model, setup, state, dt, limit, active, t_new)


@_proposal.def_jvp
def _proposal_jvp(primals, tangents):
    # The tangents of a discarded step's inputs are zeroed before its linearisation is applied, so
    # the transposed (reverse-mode) rule zeroes the cotangents that the linearisation returns,
    # rather than multiplying the step's partial derivatives by zero. Where the step is taken the
    # tangents pass unchanged.
    leaves, tree = jax.tree.flatten(primals, is_leaf=lambda a: a is None)
    t_leaves = tree.flatten_up_to(tangents)
    where = [i for i, t in enumerate(t_leaves) if t is not None]

    def propose(*diff):
        args = list(leaves)
        for i, a in zip(where, diff):
            args[i] = a
        return _propose(*jax.tree.unflatten(tree, args))

    out, linear = jax.linearize(propose, *(leaves[i] for i in where))
    _, bits, _, healthy = out
    ok = healthy & (bits == 0)
    t_out = linear(*(jnp.where(ok, t_leaves[i], jnp.zeros_like(t_leaves[i])) for i in where))
    t_out = jax.tree.map(lambda t: None if t.dtype == jax.dtypes.float0 else t, t_out)
    return out, t_out


def _propose(model, setup, state, dt, limit, active, t_new):
    scene, interp, transfer = model.scene, model.interpolator, model.transfer
    grid, body, mat = setup.grid, setup.body, setup.material
    x, v, F, t = state.x, state.v, state.F, state.t
    m = body.m
    stencil = interp.stencil(grid, body.r0, x, F, _particle_corners(state, body))
    shared = stencil.gidx is stencil.idx
    wide = stencil.w.shape[1] > 2**grid.dim  # more entries than one point's hats: GIMP, CPDI, CPDI2
    idx, gidx, S_c, g_c, w = _materialised(
        grid.dim,
        (
            stencil.idx,
            None if shared else stencil.gidx,
            stencil.S_c,
            stencil.g_c,
            stencil.w if wide else None,
        ),
    )
    stencil = stencil._replace(
        idx=idx, gidx=idx if shared else gidx, S_c=S_c, g_c=g_c, w=w if wide else stencil.w
    )

    # 1. Particle to grid: mass and momentum (artificial particles join here, and only here).
    mass, momentum = _transfer_to_grid(grid, transfer, stencil, x, v, state.C, m)
    mass_all = mass
    pre_checks = []
    if setup.layer is not None:
        layer = setup.layer
        x_a, v_a, F_a = layer.extrapolate(x), layer.extrapolate(v), layer.mean(F)
        C_a = layer.mean(state.C) if transfer.affine else None
        src = layer.src[:, 0]
        r0_a, m_a = body.r0[src], m[src]
        st_a = interp.stencil(grid, r0_a, x_a, F_a, None, gradients=False)
        mass_a, momentum_a = _transfer_to_grid(grid, transfer, st_a, x_a, v_a, C_a, m_a)
        mass_all, momentum = mass_all + mass_a, momentum + momentum_a
        lo, hi = interp.extent(r0_a, x_a, F_a, None)
        # reported on the source it is extrapolated from most: the boundary particle next to it
        nearest = jnp.take_along_axis(layer.src, jnp.argmax(layer.weights, axis=1)[:, None], axis=1)[:, 0]
        pre_checks.append((st_bits.LEFT_GRID, _on_sources(body.n, nearest, _off_grid(grid, lo, hi))))
        if st_a.ok is not None:
            pre_checks.append((st_bits.STENCIL, _on_sources(body.n, nearest, ~st_a.ok)))
    # A node mass below a few hundred ulps of a particle's mass is round-off in the weights (a domain
    # edge exactly on a node gives its far neighbour 1e-31 instead of 0), not mass: such a node counts
    # as empty. Otherwise a/m there is round-off divided by round-off, and the run depends on which.
    occupied = mass_all > setup.tiny
    v_n = jnp.where(occupied[:, None], momentum / jnp.where(occupied, mass_all, 1.0)[:, None], 0.0)

    # 2. Forces: internal, body force, tractions at the material boundary points.
    V = body.V0 * det(F)
    if interp.tracks_corners and grid.dim > 1:
        f = -shared_corner_forces(grid, stencil, state.sigma, V, state.corners, body.corner_ids)
    else:
        f = -grid.scatter(stencil.gidx, gradient_forces(stencil, state.sigma, V), stencil.gbase)
    if scene.body_force is not None:
        b = jax.vmap(scene.body_force, in_axes=(0, None))(body.X, t)
        f = f + grid.scatter(stencil.idx, (stencil.w * m[:, None])[..., None] * b[:, None, :], stencil.base)
        pre_checks.append((st_bits.SCENE_DATA, ~_finite_rows(b)))
    if state.x_traction is not None:
        tractions = scene.traction(t)  # per face (low, high of each axis), each None or a vector
        tr_face = jnp.stack([tv for tv in tractions if tv is not None])  # (loaded faces, dim)
        tp = setup.traction
        tr = tr_face
        if tp.area is not None:  # a face's traction per reference area, times each point's area
            tr = jnp.repeat(tr_face, np.asarray(tp.counts), axis=0, total_repeat_length=sum(tp.counts))
            tr = tr * tp.area[:, None]
        t_idx, t_s, _ = points_stencil(grid, state.x_traction, gradients=False)
        f = f + grid.scatter(t_idx, t_s[..., None] * tr[:, None, :])
        # a traction point off the grid would drop its force, a non-finite one spread NaN: reported on
        # the particle whose domain corner it is, before the step uses it
        tr_finite = _finite_rows(state.x_traction)
        off = _off_grid(grid, state.x_traction, state.x_traction) & tr_finite
        pre_checks.append((st_bits.NONFINITE, _on_sources(body.n, tp.owner, ~tr_finite)))
        pre_checks.append((st_bits.LEFT_GRID, _on_sources(body.n, tp.owner, off)))
        bad_tr = ~jnp.isfinite(tr_face).all(1)  # reported on a particle next to the loaded face
        pre_checks.append(
            (st_bits.SCENE_DATA, jnp.zeros(body.n, dtype=bool).at[jnp.asarray(tp.report)].set(bad_tr))
        )
    has_mass = mass > setup.tiny
    f = fold_massless(f, has_mass, grid.axes)

    # 3. Grid update; inactive nodes (no real mass) get no acceleration; walls hold v = 0.
    a = jnp.where(has_mass[:, None], f / jnp.where(has_mass, mass, 1.0)[:, None], 0.0)
    if setup.walls is not None:
        v_n = jnp.where(setup.walls, 0.0, v_n)
        a = jnp.where(setup.walls, 0.0, a)
    v_new = v_n + dt * a
    a, v_new = _materialised(grid.dim, (a, v_new))

    # 4. Particles. (MUSL: then the nodal velocity is re-projected from the new particle momenta.)
    v_p, C = transfer.update(grid, stencil, v, a, v_new, dt)
    if model.ordering == "musl":
        momentum = grid.scatter(stencil.idx, transfer.momentum(grid, stencil, x, v_p, C, m), stencil.base)
        if setup.layer is not None:
            v_a, C_a = layer.extrapolate(v_p), layer.mean(C) if transfer.affine else None
            momentum_a = transfer.momentum(grid, st_a, x_a, v_a, C_a, m_a)
            momentum = momentum + grid.scatter(st_a.idx, momentum_a, st_a.base)
        v_new = jnp.where(occupied[:, None], momentum / jnp.where(occupied, mass_all, 1.0)[:, None], 0.0)
        if setup.walls is not None:
            v_new = jnp.where(setup.walls, 0.0, v_new)
        (v_new,) = _materialised(grid.dim, (v_new,))
    x_p = x + dt * contract("nk,nkd->nd", stencil.w, grid.gather(stencil.idx, v_new, stencil.base))

    # 5. Kinematics, 6. constitutive update (at the volume-averaged F where the run asks for it).
    F_new, corners = interp.update_F(grid, body, stencil, F, state.corners, v_new, dt)
    F_old_s, F_new_s = F, F_new
    if model.volume_average is not None:
        F_old_s = _volume_averaged(model.volume_average, grid, body, stencil, x, F)
        F_new_s = _volume_averaged(model.volume_average, grid, body, stencil, x, F_new)
    if setup.regions is None:
        sigma = jax.vmap(mat.stress)(F_new_s)
        if model.viscosity is not None:
            sigma = sigma + model.viscosity.stress(mat, F_old_s, F_new_s, dt, scene.rho0, grid.h)
        e_new, internal, tension = state.e, state.internal, None
    else:
        sigma, e_new, internal, tension = _constitutive(model, setup, state, F_new_s, dt, F_old_s)
    x_tr = state.x_traction
    if x_tr is not None:
        x_tr = x_tr + dt * contract("kj,kjd->kd", t_s, grid.gather(t_idx, v_new))

    new = State(
        t=(state.step + 1).astype(dt.dtype) * dt if t_new is None else t_new,
        step=state.step + 1,
        x=x_p,
        v=v_p,
        F=F_new,
        sigma=sigma,
        C=C,
        corners=corners,
        x_traction=x_tr,
        e=e_new,
        internal=internal,
        status=state.status,
        fail_step=state.fail_step,
        fail_particle=state.fail_particle,
    )

    # Checks: a failing step is discarded, so the state kept is always the last good one.
    checks = []
    finite = _finite_particles(body, x_p, v_p, F_new, sigma, corners, e_new, internal)
    if state.x_traction is not None:
        finite = finite & ~_merge(pre_checks, st_bits.NONFINITE, body.n)
    checks.append((st_bits.NONFINITE, ~finite))
    checks.append((st_bits.NONPOSITIVE_F, det(F_new) <= 0.0))
    if e_new is not None:
        negative = _negative_energy(model, setup, e_new)
        if negative is not None:
            checks.append((st_bits.NEGATIVE_ENERGY, negative))
    if tension is not None:
        checks.append((st_bits.PRODUCTS_TENSION, tension))
    lo, hi = interp.extent(body.r0, x_p, F_new, _particle_corners(new, body))
    left_grid = _off_grid(grid, lo, hi)
    checks.append((st_bits.LEFT_GRID, left_grid | _merge(pre_checks, st_bits.LEFT_GRID, body.n)))
    if model.cfl_limit is not None:
        speed = _sound_speed(model, setup, state) + _speed(v)
        # (a relative allowance of a few ulps, so a step set exactly at the limit passes)
        allowed = model.cfl_limit * grid.h * (1.0 + 16 * jnp.finfo(dt.dtype).eps)
        checks.append((st_bits.CFL, dt * speed > allowed))
    if stencil.ok is not None:
        checks.append((st_bits.STENCIL, ~stencil.ok | _merge(pre_checks, st_bits.STENCIL, body.n)))
    if scene.body_force is not None or state.x_traction is not None:
        checks.append((st_bits.SCENE_DATA, _merge(pre_checks, st_bits.SCENE_DATA, body.n)))
    bits, particle = st_bits.combine(checks, sharded=model.devices is not None)

    if limit is not None:  # a masked step is neither taken nor checked
        active = state.step < limit if active is None else active & (state.step < limit)
    if active is not None:
        bits = jnp.where(active, bits, 0)
        healthy = (state.status == 0) & active
    else:
        healthy = state.status == 0
    return new, bits, particle, healthy


def _materialised(dim: int, fields: tuple) -> tuple:
    """Arrays that many reads share, each computed once into its own buffer (2D, 3D).

    XLA's CPU backend fuses a gather, and the elementwise work around it, with the computation of the
    arrays it reads, so that computation is redone for every read: the nodal velocity and
    acceleration (the division by the nodal mass, the fold of force off nodes without mass, the
    walls) for each of the ``2^dim`` or more reads of every node, and the stencil's node indices (the
    cell, the bounds) for each component of each read. A scatter is never fused into its consumers,
    so writing each array with one (an exact copy, every entry written once) makes the reads load it
    from memory. Measured at 102,400 particles in 2D, float32, a step takes 4.9 ms with the copies
    (and ``_speed``'s unrolled sum in the CFL check) and 12.4 ms without either (SPQ; CPDI 19.6 and
    32.6, MPQ 12.4 and 24.5); the copies alone take SPQ to 9.1 ms. The weights of a stencil wider
    than one point's ``2^dim`` hats (GIMP's ``3^dim``; CPDI's and CPDI2's hats at ``2^dim`` corners)
    are copied too, as the scatters of mass and momentum and the gather of the position update each
    read them: in 2D GIMP runs 1.26x, CPDI 1.08x and CPDI2 1.22x faster with the copy (GIMP 1.4x in
    3D), while SPQ's and MPQ's ``2^dim`` weights are cheaper to recompute than to copy (SPQ 0.89x
    with the copy). In 1D a particle reads two or three nodes, and the arrays are used unchanged.

    Args:
        dim: the space dimension (1: ``fields`` are returned as they are).
        fields: a tuple of arrays whose leading axis is the one copied (nodes or particles), or
            ``None`` entries.

    Returns:
        The same values.
    """

    return fields if dim == 1 else tuple(None if a is None else materialise(a) for a in fields)


def _volume_averaged(kind, grid, body, stencil, x, F):
    """``F_bar = (J_bar / J)^(1/dim) F`` with ``J_bar`` the cell-wise (``"cell"``) or nodal (``"node"``)
    average of ``J`` (``Model.volume_average``)."""
    J = det(F)
    V0 = body.V0
    if kind == "cell":
        cell = jnp.floor((x - grid.x_min[None, :]) / grid.h).astype(jnp.int32)
        ids = grid.flat_index([cell[:, a] for a in range(x.shape[1])])
        vol = jax.ops.segment_sum(V0 * J, ids, num_segments=grid.n_nodes)
        ref = jax.ops.segment_sum(V0, ids, num_segments=grid.n_nodes)
        J_bar = vol[ids] / ref[ids]
    else:
        vol = grid.scatter(stencil.idx, stencil.w * (V0 * J)[:, None], stencil.base)
        ref = grid.scatter(stencil.idx, stencil.w * V0[:, None], stencil.base)
        filled = ref > 0
        J_i = jnp.where(filled, vol / jnp.where(filled, ref, 1.0), 0.0)
        J_bar = contract("nk,nk->n", stencil.w, grid.gather(stencil.idx, J_i, stencil.base))
    ratio = J_bar / J
    return F * jnp.sign(ratio)[:, None, None] * jnp.abs(ratio)[:, None, None] ** (1.0 / x.shape[1])


def _constitutive(model: Model, setup: Setup, state: State, F_new, dt, F_old_all=None):
    """Stress, energy and internal variables after a step, each region by its own material.

    A material of ``F`` alone gives ``sigma(F_new)`` (plus the viscous stress). An ``AbstractEOS``
    advances its internal variables, then its energy by the trapezoid rule,

        ``e_new = e - ((p + p_new) / 2 + q) (J_new - J) / rho0``,

    solved for ``e_new`` exactly (``p_new = a + b e_new`` is affine in it), and gives
    ``sigma = -(p_new + q) I``. ``q`` is the artificial viscosity, with the sound speed at the new
    density and the old energy. An ``ElasticPlastic`` material then advances its deviatoric stress
    ``s`` (``ElasticPlastic.deviatoric``), adds it, ``sigma = -(p_new + q) I + s``, and adds its work
    ``dt (s + s_new) / 2 : D / rho_new`` to ``e`` before the solve (Wilkins' convention: ``e`` holds
    the elastic strain energy and the plastic work).

    Returns ``(sigma, e, internal, tension)``: ``tension`` marks the burnt particles of a programmed
    burn whose products' own pressure is below ``-PRODUCTS_TENSION_BOUND rho0 D^2`` (``None`` without
    a burn). ``F_old_all`` is the state's ``F`` unless given (the volume-averaged one).
    """
    body, h = setup.body, setup.grid.h
    n, dim = body.X.shape
    dtype = body.X.dtype
    groups = _groups(model, setup)
    sig, energies, internal = [], [], None if state.internal is None else dict(state.internal)
    tensions = []
    for g in groups:
        F_old, F_g = _take(state.F if F_old_all is None else F_old_all, g.index), _take(F_new, g.index)
        mat = g.material
        if not isinstance(mat, AbstractEOS):
            s_g = jax.vmap(mat.stress)(F_g)
            if model.viscosity is not None:
                s_g = s_g + model.viscosity.stress(mat, F_old, F_g, dt, g.rho0, h)
            sig.append(s_g)
            if state.e is not None:
                energies.append(_take(state.e, g.index))
            continue
        keys = _internal_keys(mat, dim, dtype)
        z_old = _subset(state.internal, keys, g.index)
        J_old, J_new = det(F_old), det(F_g)
        X_g = _take(body.X, g.index)
        z_new = jax.vmap(mat.update_internal, in_axes=(0, 0, None, None, 0, 0))(
            z_old, X_g, state.t, dt, J_old, J_new
        )
        plastic = isinstance(mat, ElasticPlastic)
        if plastic:  # the deviatoric stress and its power per unit volume
            z_new, s_dev, s_power = jax.vmap(mat.deviatoric, in_axes=(0, 0, 0, None))(z_new, F_old, F_g, dt)
        e_old = _take(state.e, g.index)
        rho_old, rho_new = g.rho0 / J_old, g.rho0 / J_new
        p_old = jax.vmap(mat.pressure)(rho_old, e_old, z_old)
        q = jnp.zeros_like(J_new)
        if model.viscosity is not None:
            c = jax.vmap(mat.sound_speed)(rho_new, e_old, z_new)
            q = model.viscosity.pressure_of(J_old, J_new, dt, rho_new, c, h)
        a, b = jax.vmap(mat.pressure_terms)(rho_new, z_new)
        dJ = (J_new - J_old) / g.rho0
        shear = model.viscosity is not None and model.viscosity.c_shear is not None
        e_start = e_old
        if shear:  # the shear viscosity's stress, and its work as heat
            s_visc, power = model.viscosity.shear_stress(F_old, F_g, dt, rho_new, c, h)
            e_start = e_old + dt * power
        if plastic:  # the deviatoric work
            e_start = e_start + dt * s_power / rho_new
        e_g = (e_start - (0.5 * p_old + q + 0.5 * a) * dJ) / (1.0 + 0.5 * b * dJ)
        s_g = _eos_stress(a + b * e_g + q, dim, dtype)
        if plastic:
            s_g = s_g + s_dev
        sig.append(s_g + s_visc if shear else s_g)
        energies.append(e_g)
        if isinstance(mat, ProgrammedBurn):
            p_products = jax.vmap(mat.products.pressure)(rho_new, e_g)
            bound = -PRODUCTS_TENSION_BOUND * g.rho0 * jnp.square(mat.D)
            tensions.append((g.index, (z_new["lambda"] > 0.0) & (p_products < bound)))
        if z_new is not None:
            for k in keys:
                internal[k] = internal[k].at[g.index].set(z_new[k]) if g.index is not None else z_new[k]
    e = None if state.e is None else _assemble(energies, groups, n)
    tension = None
    if tensions:
        tension = jnp.zeros((n,), dtype=bool)
        for index, mask in tensions:
            tension = mask if index is None else tension.at[index].set(mask)
    return _assemble(sig, groups, n), e, internal, tension


@eqx.filter_jit
def material_stress(model, F, e, internal):
    """The stress a step of ``model`` without viscosity leaves at deformation ``F``, energy ``e`` and
    internal variables ``internal`` (each region by its own material, as ``_constitutive`` computes
    it: the two change together), and for each particle the size of the terms it sums; ``long_run``
    checks a saved stress against it.

    Returns:
        ``(sigma, size)``: ``(n, dim, dim)`` and ``(n,)``. ``size`` is the largest magnitude of the
        material's parameters for a material of ``F`` alone, and ``|a| + |b e|`` (plus the
        deviatoric stress of an ``ElasticPlastic``) for an equation of state ``p = a + b e``.
    """
    prepared = setup(model)
    n, dim = F.shape[0], F.shape[-1]
    groups = _groups(model, prepared)
    stress, size = [], []
    for g in groups:
        F_g, material = _take(F, g.index), g.material
        if isinstance(material, AbstractEOS):
            z = _subset(internal, _internal_keys(material, dim, F.dtype), g.index)
            e_g = _take(e, g.index)
            a, b = jax.vmap(material.pressure_terms)(g.rho0 / det(F_g), z)
            s_g = _eos_stress(a + b * e_g, dim, F.dtype)
            size_g = jnp.abs(a) + jnp.abs(b * e_g)
            if isinstance(material, ElasticPlastic):
                deviatoric = jax.vmap(functools.partial(material.stress_of, dim=dim))(z)
                s_g = s_g + deviatoric
                size_g = size_g + jnp.max(jnp.abs(deviatoric), axis=(1, 2))
        else:
            s_g = jax.vmap(material.stress)(F_g)
            leaves = [jnp.max(jnp.abs(p)) for p in jax.tree.leaves(material) if eqx.is_inexact_array(p)]
            largest = jnp.max(jnp.stack(leaves)).astype(F.dtype) if leaves else jnp.zeros((), F.dtype)
            size_g = jnp.full(F_g.shape[:1], largest)
        stress.append(s_g)
        size.append(size_g)
    return _assemble(stress, groups, n), _assemble(size, groups, n)


def fold_massless(
    f: Float[Array, "n_nodes dim"], has_mass: Bool[Array, " n_nodes"], axes: tuple[int, ...] | None = None
) -> Float[Array, "n_nodes dim"]:
    """Move force that landed on a node without mass onto the adjacent node with mass.

    A node without (real) mass has no acceleration, so force there would be lost and momentum
    would not balance. This happens where a query point reaches past the last node with mass: a
    traction point or an MPQ/GIMP domain corner that the body's expansion carried into the next
    cell. Folding onto the neighbour (the left one first) gives the boundary node the whole
    boundary force, as when the boundary point sits exactly on it, so the result is continuous in
    the boundary position, and the total force is unchanged. Force with no massive neighbour
    within one node is dropped (no interpolator here reaches that far from every mass).

    On a grid of ``axes`` nodes per axis (2D, 3D), force on a node with massive neighbours along
    several axes is split equally among those axes (the lower neighbour first along each), so the
    axes are treated alike. Force on a node whose massive neighbours are only diagonal goes along one
    axis at a time, axis 0 first: a node that can reach mass along the later axes keeps it for them;
    failing that, it moves to a neighbour that can (so force on a node diagonal to the body's corner
    reaches the corner node in two moves). Force with no mass within one node along every axis is
    dropped.

    Args:
        f: nodal forces.
        has_mass: which nodes have mass.
        axes: nodes along each axis (``None`` or one axis: 1D).

    Returns:
        The folded forces.
    """
    zero = jnp.zeros_like(f[:1])
    if axes is None or len(axes) == 1:
        stray = jnp.where(has_mass[:, None], 0.0, f)
        left_ok = jnp.concatenate([jnp.zeros((1,), dtype=bool), has_mass[:-1]])
        right_ok = jnp.concatenate([has_mass[1:], jnp.zeros((1,), dtype=bool)])
        to_left = jnp.where(left_ok[:, None], stray, 0.0)
        to_right = jnp.where(~left_ok[:, None] & right_ok[:, None], stray, 0.0)
        kept = jnp.where(has_mass[:, None], f, 0.0)
        return kept + jnp.concatenate([to_left[1:], zero]) + jnp.concatenate([zero, to_right[:-1]])

    def shift(x, by, a):  # x[i - by] along axis a, zero-filled
        z = jnp.zeros_like(jax.lax.slice_in_dim(x, 0, 1, axis=a))
        if by > 0:
            return jnp.concatenate([z, jax.lax.slice_in_dim(x, 0, x.shape[a] - 1, axis=a)], axis=a)
        return jnp.concatenate([jax.lax.slice_in_dim(x, 1, x.shape[a], axis=a), z], axis=a)

    d = len(axes)
    m = has_mass.reshape(axes)
    reach = [m] * d  # reach[a]: mass within one node along each of the axes after a
    for a in range(d - 2, -1, -1):
        r = reach[a + 1]
        reach[a] = r | shift(r, 1, a + 1) | shift(r, -1, a + 1)
    f = f.reshape(axes + f.shape[1:])
    kept = jnp.where(m[..., None], f, 0.0)
    stray = jnp.where(m[..., None], 0.0, f)
    # Force on a node with massive neighbours along several axes is split equally among those axes,
    # so the fold treats the axes alike (a square body stays symmetric about its diagonal).
    near = [shift(m, 1, a) | shift(m, -1, a) for a in range(d)]
    count = functools.reduce(operator.add, [jnp.where(n_a, 1.0, 0.0) for n_a in near])
    for a in range(d):
        share = jnp.where(near[a], 1.0, 0.0) / jnp.maximum(count, 1.0)
        part = stray * share[..., None]
        left_m = shift(m, 1, a)
        kept = kept + shift(jnp.where(left_m[..., None], part, 0.0), -1, a)
        kept = kept + shift(jnp.where((~left_m & shift(m, -1, a))[..., None], part, 0.0), 1, a)
    stray = jnp.where((count > 0)[..., None], 0.0, stray)
    for a in range(d):
        T = reach[a]
        left_m, right_m = shift(m, 1, a), shift(m, -1, a)
        left_T, right_T = shift(T, 1, a), shift(T, -1, a)
        stays = ~left_m & ~right_m & T
        go_left = left_m | (~right_m & ~stays & left_T)
        go_right = ~go_left & (right_m | (~stays & right_T))
        moved = (
            jnp.where((~go_left & ~go_right)[..., None], stray, 0.0)
            + shift(jnp.where(go_left[..., None], stray, 0.0), -1, a)
            + shift(jnp.where(go_right[..., None], stray, 0.0), 1, a)
        )
        kept = kept + jnp.where(m[..., None], moved, 0.0)
        stray = jnp.where(m[..., None], 0.0, moved)
    return kept.reshape((-1,) + f.shape[d:])


def _negative_energy(model: Model, setup: Setup, e) -> Bool[Array, " n"] | None:
    """The particles whose specific internal energy ``e`` is negative where their material holds it
    non-negative (``AbstractEOS.nonnegative_energy``); ``None`` where no material does (nothing to
    check, nothing compiled)."""
    groups = _groups(model, setup)
    bounded = [isinstance(g.material, AbstractEOS) and g.material.nonnegative_energy() for g in groups]
    if all(bounded):
        return e < 0.0
    if not any(bounded):
        return None
    parts = [jnp.full(_take(e, g.index).shape, b) for g, b in zip(groups, bounded)]
    return (e < 0.0) & _assemble(parts, groups, e.shape[0])


def _finite_particles(body: Body, x, v, F, sigma, corners, e, internal) -> Bool[Array, " n"]:
    """Whether every field of each particle is finite (the corners, energy and internal variables
    where the run has them): the ``NONFINITE`` check of the initial state and of every step."""
    finite = _finite_rows(x) & _finite_rows(v) & _finite_rows(F) & _finite_rows(sigma)
    if corners is not None:
        finite = finite & _finite_rows(body.particle_corners(corners))
    if e is not None:
        finite = finite & jnp.isfinite(e)
    for val in (internal or {}).values():
        finite = finite & jnp.isfinite(val)
    return finite


def _finite_rows(a: Array) -> Bool[Array, " n"]:
    """Whether every entry of each particle's ``a[p]`` is finite, as unrolled ANDs over the entries.

    ``jnp.isfinite(a).all(axis)`` is a reduce over a short axis, a slow library call on XLA's CPU
    backend: with four of them the fused loop of the step's checks took 41 ms of a 100-step 2D run of
    102,400 particles (SPQ, float32, about 490 ms in all), and 15 ms with the ANDs unrolled."""
    flat = a.reshape(a.shape[0], math.prod(a.shape[1:]))
    return functools.reduce(operator.and_, [jnp.isfinite(flat[:, j]) for j in range(flat.shape[1])])


def _speed(v: Float[Array, "n dim"]) -> Float[Array, " n"]:
    """``|v|`` per particle, with a zero derivative (not NaN) at rest: ``jnp.linalg.norm``'s is NaN at 0,
    and a run to an end time differentiates its step ``cfl h / max(c + |v|)`` (a particle at rest).
    The squares are added in unrolled adds: a reduce over the short axis is a library call on XLA's
    CPU backend (the 2D step at 102,400 particles, float32, with the copies of ``_materialised``:
    9.1 ms with the reduce, 8.3 ms without, measured)."""
    sq = functools.reduce(operator.add, [v[:, a] * v[:, a] for a in range(v.shape[1])])
    pos = sq > 0.0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def _off_grid(grid: Grid, lo, hi):
    """Whether a particle's query extent ``[lo, hi]`` (per axis) reaches past the grid along any axis."""
    return any_axis((lo < grid.x_min[None, :]) | (hi >= grid.x_max[None, :]))


def _on_sources(n: int, src, mask):
    """A failure of a point the step carries beside the particles (an artificial particle, a traction
    point), reported on the real particle ``src`` it belongs to."""
    return jnp.zeros(n, dtype=jnp.int32).at[src].max(mask.astype(jnp.int32)) > 0


def _merge(checks, bit, n):
    masks = [mask for b, mask in checks if b == bit]
    out = jnp.zeros(n, dtype=bool)
    for mask in masks:
        out = out | mask
    return out
