"""Small helpers used across modules."""

import dataclasses
import functools
import operator

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils
from jaxtyping import Array, Float

from ._checks import check_real, check_scalar


def as_float(x: object) -> Float[Array, ""]:
    """A continuous parameter as a 0-d array of the default float dtype (float64 once x64 is enabled):
    the converter of every parameter field of scenes, materials and runs.

    It takes any object and checks it itself (a tracer passes unchanged in value), so that a module
    can name the parameter first: scenes, materials and viscosities check their ``as_float`` fields
    by name before they are converted (``check_real_fields``: "beta must be a real number, got
    'abc'"); this message, without a name, is for a module that does not.

    Args:
        x: a real number (``Real[ArrayLike, ""]``), or a 0-d array (a tracer under ``jax.grad`` or
            ``jax.vmap``).

    Returns:
        The array.

    Raises:
        ValueError: ``x`` is not a real number (a string, ``None``, a complex number, ...).
    """
    check_real("a continuous parameter", x)
    return jnp.asarray(x, dtype=jnp.result_type(float))


ONE_VALUE = (
    ": to run several values, jax.vmap over simulate (building the scene in it) or use jaxmpm.ensemble"
)
"""How to run several values of a parameter, for the message that refuses an array of them."""


def check_real_fields(module: object, batch: str | None = None) -> None:
    """Name the ``as_float`` field of ``module`` that is not a number, before the converters run
    (``as_float`` cannot name it): called by the ``__post_init__`` of scenes, materials and
    viscosities, which runs on the values as given. Tracers pass.

    Args:
        module: a dataclass (an ``eqx.Module``) whose fields hold the values as given.
        batch: ``None`` to accept an array of any shape; else each field must be one number, and a
            field with a shape is refused with this appended (how to run several values instead).

    Raises:
        ValueError: a field is not a real number ("P0 must be a real number, got None"), or, with
            ``batch``, is an array with a shape ("P0 must be one number, got an array of shape (2,)").
    """
    for f in dataclasses.fields(module):
        if f.metadata.get("converter") is as_float:
            value = getattr(module, f.name)
            if type(value) is float or type(value) is int:
                continue  # the common case, one number: skip the general checks (a few us each)
            check_real(f.name, value)
            if batch is not None:
                check_scalar(f.name, value, batch)


def static_fraction(x: object, name: str = "x0") -> float:
    """A static parameter (where two regions meet, a fraction of a length) as a Python float.

    Args:
        x: one real number.
        name: the parameter's name, for the message.

    Returns:
        ``float(x)``.

    Raises:
        ValueError: ``x`` is not a real number ("x0 must be a real number, got 'abc'") or is an array
            with a shape (a static parameter is one number).
    """
    check_real(name, x)
    check_scalar(name, x, " (a static parameter: it fixes the regions' particles)")
    return float(x)


def det(F):
    """``det F`` of each particle: closed forms up to 3x3 (the entry itself in 1D), which fuse, where
    ``jnp.linalg.det`` runs an LU factorisation per matrix.

    Args:
        F: matrices, ``(..., dim, dim)``.

    Returns:
        Their determinants, ``(...)``.
    """
    d = F.shape[-1]
    if d == 1:
        return F[..., 0, 0]
    if d == 2:
        return F[..., 0, 0] * F[..., 1, 1] - F[..., 0, 1] * F[..., 1, 0]
    if d == 3:
        a, b, c = F[..., 0, 0], F[..., 0, 1], F[..., 0, 2]
        return (
            a * (F[..., 1, 1] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 1])
            - b * (F[..., 1, 0] * F[..., 2, 2] - F[..., 1, 2] * F[..., 2, 0])
            + c * (F[..., 1, 0] * F[..., 2, 1] - F[..., 1, 1] * F[..., 2, 0])
        )
    return jnp.linalg.det(F)


def power(x: Array, p: Array) -> Array:
    """``x ** p`` for bases ``x > 0`` (volume ratios, specific volumes): the materials' power laws.

    In float32 it is computed as ``exp(p log x)``: XLA's CPU backend runs a float32 ``power`` as one
    scalar library call per element, and ``exp`` and ``log`` as vectorised polynomials that fuse with
    their neighbours (102,400 values: 0.67 against 0.19 ms, ``experiments/power_forms.py``; with
    ``**`` a gas's pressure takes 18% of a 1D SPQ step of 1M particles). The price is accuracy: it
    rounds the exponent ``p log x``, and is within ``2 (1 + |p log x|)`` ulps of the exact power
    (``tests/test_power.py``; 2-3 ulps for a gas's ``|log J| < 0.1``), where ``**`` is within 0.5-3
    ulps. A base ``x <= 0`` gives what ``**`` gives for a non-integer ``p``: 0 or infinity at 0, NaN
    below. Every other dtype uses ``**`` itself: in float64 both forms make a library call per
    element (``exp(p log x)`` took 0.5-0.9 ms against 0.7-1.0 in two measurements, its ``log`` the
    call), and ``**`` keeps float64 results bit for bit what they are.

    Args:
        x: the bases, positive.
        p: the exponent.

    Returns:
        ``x ** p``.
    """
    if jnp.result_type(x) == jnp.float32:
        return jnp.exp(p * jnp.log(x))
    return x**p


def contract(spec: str, a: Array, b: Array) -> Array:
    """``jnp.einsum(spec, a, b)`` as a broadcast product and a sum, for the step's tiny per-particle
    contractions (stencil width by ``dim``).

    XLA turns an einsum into a ``dot_general`` and a sum into a ``reduce``; its CPU backend hands both
    to a library kernel that runs millions of length-2 products one by one, several times slower
    than unrolled elementwise adds, which fuse with their neighbours (measured on the 1D step, see
    experiments/bench.py). Two operands, no repeated letter within one operand.

    Args:
        spec: the einsum specification, ``"ab,bc->ac"``.
        a: the first operand.
        b: the second operand.

    Returns:
        ``jnp.einsum(spec, a, b)``, summed in unrolled adds.
    """
    ins, out = spec.replace(" ", "").split("->")
    sa, sb = ins.split(",")
    letters = sa + "".join(c for c in sb if c not in sa)

    def expand(x, s):
        perm = [s.index(c) for c in letters if c in s]
        x = jnp.transpose(x, perm) if perm != sorted(perm) else x
        shape = [x.shape[[c for c in letters if c in s].index(c)] if c in s else 1 for c in letters]
        return jnp.reshape(x, shape)

    prod = expand(a, sa) * expand(b, sb)
    summed = tuple(i for i, c in enumerate(letters) if c not in out)
    kept = [c for c in letters if c in out]
    for axis in reversed(summed):  # unrolled adds: a reduce op is again a slow custom fusion
        parts = [jax.lax.index_in_dim(prod, i, axis, keepdims=False) for i in range(prod.shape[axis])]
        prod = functools.reduce(operator.add, parts)
    perm = [kept.index(c) for c in out]
    return jnp.transpose(prod, perm) if perm != sorted(perm) else prod


def materialise(a: Array) -> Array:
    """``a`` written once into its own buffer, so that XLA's CPU backend does not fuse its computation
    into each of its readers and redo it for every read (a scatter is never fused into its consumers;
    this one is an exact copy, every entry written once). See ``jaxmpm._step._materialised``.

    Args:
        a: an array with a leading axis.

    Returns:
        The same values.
    """
    i = jnp.arange(a.shape[0], dtype=jnp.int32)
    return jnp.zeros_like(a).at[i].set(a, indices_are_sorted=True, unique_indices=True)


def adjugate(A):
    """The adjugate ``adj A`` (``A^-1 = adj A / det A``) of each matrix, in closed form for ``dim <= 3``
    (the cofactor transpose; 1 in 1D).

    Args:
        A: matrices, ``(..., dim, dim)``.

    Returns:
        Their adjugates.
    """
    d = A.shape[-1]
    if d == 1:
        return jnp.ones_like(A)
    if d == 2:
        a, b, c, e = A[..., 0, 0], A[..., 0, 1], A[..., 1, 0], A[..., 1, 1]
        return jnp.stack([jnp.stack([e, -b], -1), jnp.stack([-c, a], -1)], -2)
    if d == 3:
        rows = []
        for i in range(3):
            row = []
            for j in range(3):  # adj[i, j] = cofactor[j, i]
                r = [k for k in range(3) if k != j]
                c = [k for k in range(3) if k != i]
                minor = A[..., r[0], c[0]] * A[..., r[1], c[1]] - A[..., r[0], c[1]] * A[..., r[1], c[0]]
                row.append(minor if (i + j) % 2 == 0 else -minor)
            rows.append(jnp.stack(row, -1))
        return jnp.stack(rows, -2)
    return det(A)[..., None, None] * jnp.linalg.inv(A)


def lattice(counts):
    """The integer multi-indices of a ``counts[0] x counts[1] x ...`` lattice.

    Args:
        counts: points along each axis.

    Returns:
        A static ``(prod(counts), len(counts))`` array, the last axis fastest (the flat order of grids
        and bodies).
    """
    import numpy as np

    return np.indices(tuple(counts)).reshape(len(counts), -1).T


def corner_signs(dim: int):
    """The ``2^dim`` corners of the reference cube ``[-1, 1]^dim``.

    Args:
        dim: number of space dimensions.

    Returns:
        A static ``(2^dim, dim)`` array, corner ``c`` having ``+1`` along axis ``a`` where bit ``dim -
        1 - a`` of ``c`` is set (the last axis fastest; in 1D: left, right).
    """
    import numpy as np

    c = np.arange(2**dim)[:, None]
    bits = (c >> (dim - 1 - np.arange(dim))[None, :]) & 1
    return (2 * bits - 1).astype(np.float64)


def host(a) -> np.ndarray:
    """``a`` as a NumPy array on this process, also when it is spread over several processes' devices
    (then gathered from all of them: a collective, which every process must call at the same point).

    Args:
        a: an array.

    Returns:
        The whole array.
    """
    if isinstance(a, jax.Array) and not a.is_fully_addressable:
        return np.asarray(multihost_utils.process_allgather(a, tiled=True))
    return np.asarray(a)
