"""ParaView output: particles and grid fields as VTK files, and a ``.pvd`` time series.

Legacy VTK, binary (big-endian, as the format requires), which ParaView, VisIt and meshio read:

- particles: ``UNSTRUCTURED_GRID`` of one vertex cell per particle, point data ``v`` (vector), ``F`` and
  ``sigma`` (3x3 tensors, padded with the identity for ``F`` and zeros for ``sigma`` beyond
  ``dim``), ``J = det F``, ``X`` (reference position), ``rho``, ``p``, ``region``, and ``e`` and
  ``internal.<variable>`` where the run carries them;
- grid: ``STRUCTURED_POINTS`` over the nodes, point data ``mass`` and ``velocity`` from the
  particle-to-grid transfer the step itself makes (the same stencil and transfer), without the
  artificial particles: what the real body puts on the grid.

Positions have ``dim`` components and are padded to 3 with zeros (a 1D run lies along x, a 2D run
in the x-y plane). The grid file has the grid's nodes along each axis, in VTK's order (x fastest).
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._checks import check_bool
from ._files import write_whole
from ._util import det


def _pad_vectors(a: np.ndarray) -> np.ndarray:
    out = np.zeros((a.shape[0], 3))
    out[:, : a.shape[1]] = a
    return out


def _pad_tensors(a: np.ndarray, fill_identity: bool) -> np.ndarray:
    n, d = a.shape[0], a.shape[1]
    out = np.zeros((n, 3, 3))
    if fill_identity:
        out[:] = np.eye(3)
    out[:, :d, :d] = a
    return out.reshape(n, 9)


def _be(a: np.ndarray, dtype: str) -> bytes:
    return np.ascontiguousarray(a, dtype=dtype).tobytes()


def _point_data(fields: Mapping[str, np.ndarray], n: int) -> bytes:
    parts = [f"POINT_DATA {n}\n".encode()]
    for name, a in fields.items():
        a = np.asarray(a, dtype=float)
        if a.shape[0] != n:
            raise ValueError(f"field {name!r} has {a.shape[0]} values, expected {n}")
        if a.ndim == 1:
            parts.append(f"SCALARS {name} double 1\nLOOKUP_TABLE default\n".encode())
        elif a.ndim == 2 and a.shape[1] == 3:
            parts.append(f"VECTORS {name} double\n".encode())
        elif a.ndim == 2 and a.shape[1] == 9:
            parts.append(f"TENSORS {name} double\n".encode())
        else:
            raise ValueError(f"field {name!r}: shape {a.shape} is not (n,), (n, 3) or (n, 9)")
        parts.append(_be(a, ">f8") + b"\n")
    return b"".join(parts)


def write_particles(
    path: str | os.PathLike, x, fields: Mapping[str, np.ndarray] | None = None, *, overwrite: bool = False
) -> pathlib.Path:
    """Write particles as a legacy VTK ``UNSTRUCTURED_GRID`` of vertices.

    Args:
        path: the file to write.
        x: positions, ``(n, dim)``.
        fields: point data: arrays of shape ``(n,)`` (scalars), ``(n, 3)`` (vectors) or ``(n, 9)``
            (3x3 tensors, row-major).
        overwrite: replace a file already at ``path`` (else it is refused).

    Returns:
        ``path``.

    Raises:
        ValueError: a field of the wrong length or shape, or ``overwrite`` is not a bool.
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
    """
    path = pathlib.Path(path)
    _refuse_existing([path], overwrite)
    x = _pad_vectors(np.asarray(x, dtype=float))
    n = x.shape[0]
    cells = np.stack([np.ones(n, dtype=np.int64), np.arange(n)], axis=1)
    body = [
        b"# vtk DataFile Version 3.0\njaxmpm particles\nBINARY\nDATASET UNSTRUCTURED_GRID\n",
        f"POINTS {n} double\n".encode(),
        _be(x, ">f8"),
        f"\nCELLS {n} {2 * n}\n".encode(),
        _be(cells, ">i4"),
        f"\nCELL_TYPES {n}\n".encode(),
        _be(np.ones(n), ">i4"),  # VTK_VERTEX
        b"\n",
        _point_data(fields or {}, n),
    ]
    _write(path, b"".join(body))
    return path


def write_grid(
    path: str | os.PathLike, grid, fields: Mapping[str, np.ndarray], *, overwrite: bool = False
) -> pathlib.Path:
    """Write node fields of a grid as legacy VTK ``STRUCTURED_POINTS``.

    Args:
        path: the file to write.
        grid: the ``jm.Grid``.
        fields: as for ``write_particles``, one value per node (in jaxmpm's flat order).
        overwrite: replace a file already at ``path`` (else it is refused).

    Returns:
        ``path``.

    Raises:
        ValueError: a field of the wrong length or shape, or ``overwrite`` is not a bool.
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
    """
    path = pathlib.Path(path)
    _refuse_existing([path], overwrite)
    dim = grid.dim
    shape = list(grid.axes) + [1] * (3 - dim)
    origin = [float(o) for o in np.asarray(grid.x_min)] + [0.0] * (3 - dim)
    h = float(grid.h)
    spacing = [h] * dim + [1.0] * (3 - dim)
    if dim > 1:  # VTK runs x fastest; jaxmpm's flat order runs the last axis fastest
        fields = {
            k: np.asarray(v)
            .reshape(tuple(grid.axes) + np.shape(v)[1:])
            .transpose(tuple(reversed(range(dim))) + tuple(range(dim, np.ndim(v) + dim - 1)))
            .reshape((grid.n_nodes,) + np.shape(v)[1:])
            for k, v in fields.items()
        }
    header = (
        "# vtk DataFile Version 3.0\njaxmpm grid\nBINARY\nDATASET STRUCTURED_POINTS\n"
        f"DIMENSIONS {' '.join(str(s) for s in shape)}\n"
        f"ORIGIN {' '.join(repr(o) for o in origin)}\n"
        f"SPACING {' '.join(repr(s) for s in spacing)}\n"
    )
    _write(path, header.encode() + _point_data(fields, grid.n_nodes))
    return path


def _refuse_existing(paths: list[pathlib.Path], overwrite) -> None:  # overwrite: checked here
    """Refuse, before anything is written, to replace a file already at one of ``paths`` unless
    ``overwrite``."""
    check_bool("overwrite", overwrite)
    if overwrite:
        return
    for path in paths:
        if os.path.lexists(path):
            raise FileExistsError(f"{path} already exists: pass overwrite=True to replace it")


def _write(path: pathlib.Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (``write_whole``)."""
    write_whole(path, lambda f: f.write(data))


def nodal_fields(model, state, setup=None) -> dict[str, np.ndarray]:
    """Nodal ``mass`` and ``velocity`` (momentum / mass, zero on empty nodes) of ``state``, from the
    particle-to-grid transfer of ``model``, real particles only.

    Args:
        model: the run (a ``jm.Model``).
        state: the state.
        setup: the run's ``jm.setup(model)``, derived here when not given.

    Returns:
        ``{"mass": (n_nodes,), "velocity": (n_nodes, 3)}``.
    """
    from . import _step

    setup = eqx.filter_jit(_step.setup)(model) if setup is None else setup
    mass, velocity = _nodal(model, setup, state)
    return {"mass": np.asarray(mass), "velocity": _pad_vectors(np.asarray(velocity))}


@eqx.filter_jit  # one program a series (op by op, each frame would dispatch a transfer's every primitive)
def _nodal(model, setup, state):
    from . import _step

    mass, momentum = _step.particle_to_grid(model, setup, state)
    occupied = mass > setup.tiny
    return mass, jnp.where(occupied[:, None], momentum / jnp.where(occupied, mass, 1.0)[:, None], 0.0)


@eqx.filter_jit  # one program a series, as _nodal
def _smoothness(state, body):
    from .metrics import corner_jacobians, domain_corners, rotation_angle

    return rotation_angle(state), jnp.min(corner_jacobians(domain_corners(state, body), body), axis=1)


def particle_fields(state, body) -> dict[str, np.ndarray]:
    """The particle point data written by ``write_series``.

    Args:
        state: the state.
        body: the reference configuration.

    Returns:
        ``v``, ``F``, ``sigma``, ``J`` and ``X``, padded to 3 components (``F`` and ``sigma`` to 3x3),
        ``rho`` (current density), ``p`` (``-tr(sigma) / dim``), ``region`` (0 for a body of one
        region), the smoothness measures ``rotation`` (the angle of ``F``'s polar rotation, radians:
        ``jaxmpm.metrics.rotation_angle``) and ``corner_jacobian_min`` (the smallest Jacobian of the
        particle's domain at its corners, ``<= 0`` where it is folded or inverted:
        ``jaxmpm.metrics.corner_jacobians``), and where the run has them ``e`` and
        ``internal.<variable>``.
    """
    rotation, corner_jacobian_min = _smoothness(state, body)
    J = np.asarray(det(state.F))
    dim = state.F.shape[-1]
    out = {
        "v": _pad_vectors(np.asarray(state.v)),
        "F": _pad_tensors(np.asarray(state.F), fill_identity=True),
        "sigma": _pad_tensors(np.asarray(state.sigma), fill_identity=False),
        "J": J,
        "X": _pad_vectors(np.asarray(body.X)),
        "rho": np.asarray(body.m) / (np.asarray(body.V0) * J),
        "p": -np.trace(np.asarray(state.sigma), axis1=1, axis2=2) / dim,
        "region": np.zeros(body.n) if body.region is None else np.asarray(body.region, dtype=float),
        "rotation": np.asarray(rotation),
        "corner_jacobian_min": np.asarray(corner_jacobian_min),
    }
    if state.e is not None:
        out["e"] = np.asarray(state.e)
    for k, val in (state.internal or {}).items():
        out[f"internal.{k}"] = np.asarray(val)
    return out


def write_series(
    out_dir: str | os.PathLike, model, solution, *, overwrite: bool = False
) -> list[pathlib.Path]:
    """One particle file and one grid file per saved time of ``solution`` (run with a ``SaveAt`` that
    keeps ``x``, ``v``, ``F`` and ``sigma``, and ``corners`` for MPQ, ``C`` for APIC), plus
    ``particles.pvd`` and ``grid.pvd``, the collections ParaView opens as time series.

    Saved times after a breakdown, or past ``t_end`` in a run to an end time, repeat the final
    state and are left out. The final state (after a breakdown, the last good one) is the last
    frame, added when it falls between saves. A file already in ``out_dir`` under one of the names
    written is refused unless ``overwrite``, and replaced with it (each file is written whole, then
    renamed into place); files of other names are left as they are. The model, the solution and the
    files already there are checked before anything is written.

    Args:
        out_dir: the directory to write to (made if missing).
        model: the run (a ``jm.Model``).
        solution: its ``Solution``.
        overwrite: replace the files already in ``out_dir`` under the names written (else refused).

    Returns:
        The paths written.

    Raises:
        ValueError: the solution has no history, or its history lacks a field the files need; it
            holds a batch (an ensemble's); the model is not the solution's run; ``out_dir`` is a
            file; or ``overwrite`` is not a bool.
        FileExistsError: a file to write is already in ``out_dir`` and ``overwrite`` is ``False``.
    """
    check_bool("overwrite", overwrite)
    if solution.history is None:
        raise ValueError(
            "write_series needs a solution with a history: simulate(..., saveat=SaveAt(every=k))"
        )
    if solution.state.x.ndim != 2:
        raise ValueError(
            f"write_series writes one run, and this solution holds a batch (x of shape "
            f"{tuple(solution.state.x.shape)}): write each member (Ensemble.member(i))"
        )
    needed = ["x", "v", "F", "sigma"]
    needed += ["corners"] if model.interpolator.tracks_corners else []
    needed += ["C"] if model.transfer.affine else []
    needed += ["e"] if solution.state.e is not None else []
    needed += [f"internal.{k}" for k in solution.state.internal or {}]
    missing = [f for f in needed if f not in solution.history]
    if missing:
        raise ValueError(f"the saved history lacks {missing}: add them to SaveAt(fields=...)")
    ts = np.asarray(solution.ts)
    t_last = float(solution.state.t)
    keep = []  # saved times up to the final state's, each once (a run to t_end, or a broken run,
    for i, t in enumerate(ts):  # saves its final state again at every save that follows)
        if t <= t_last * (1 + 1e-12) and (not keep or t > ts[keep[-1]]):
            keep.append(i)
    frames = [(ts[i], _state_at(solution, i)) for i in keep]
    if not keep or t_last > ts[keep[-1]] * (1 + 1e-12):
        frames.append((t_last, solution.state))
    from ._step import setup

    prepared = eqx.filter_jit(setup)(model)  # once for the series: the grid and the body do not change
    X, X_model = np.asarray(solution.body.X), np.asarray(prepared.body.X)
    if X.shape != X_model.shape or not np.allclose(X, X_model, rtol=1e-12, atol=0.0):
        raise ValueError(
            f"the model is not the solution's run: its body has {X_model.shape[0]} particles in "
            f"{X_model.shape[1]}D, the solution's {X.shape[0]} in {X.shape[1]}D (or at other reference "
            "positions)"
        )
    out = pathlib.Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {out_dir} is a file, not a folder")
    names = [f"{kind}_{frame:05d}.vtk" for frame in range(len(frames)) for kind in ("particles", "grid")]
    _refuse_existing([out / name for name in names + ["particles.pvd", "grid.pvd"]], overwrite)
    out.mkdir(parents=True, exist_ok=True)
    paths, entries = [], {"particles": [], "grid": []}
    for frame, (t, state) in enumerate(frames):
        fields = particle_fields(state, solution.body)
        p = write_particles(out / f"particles_{frame:05d}.vtk", state.x, fields, overwrite=overwrite)
        g = write_grid(
            out / f"grid_{frame:05d}.vtk",
            prepared.grid,
            nodal_fields(model, state, prepared),
            overwrite=overwrite,
        )
        paths += [p, g]
        entries["particles"].append((t, p.name))
        entries["grid"].append((t, g.name))
    for kind, items in entries.items():
        lines = ['<?xml version="1.0"?>', '<VTKFile type="Collection" version="0.1">', "<Collection>"]
        lines += [f'<DataSet timestep="{float(t)!r}" file="{name}"/>' for t, name in items]
        lines += ["</Collection>", "</VTKFile>", ""]
        pvd = out / f"{kind}.pvd"
        _write(pvd, "\n".join(lines).encode())
        paths.append(pvd)
    return paths


def _state_at(solution, i: int):
    """The state of saved frame ``i`` (fields not saved keep the final state's values)."""
    import equinox as eqx

    from ._simulate import STATE_FIELDS

    names = [n for n in solution.history if n in STATE_FIELDS]
    values = [solution.history[n][i] for n in names]
    state = eqx.tree_at(lambda s: [getattr(s, n) for n in names], solution.state, values)
    keys = [n.split(".", 1)[1] for n in solution.history if n.startswith("internal.")]
    if keys:
        internal = {**state.internal, **{k: solution.history[f"internal.{k}"][i] for k in keys}}
        state = eqx.tree_at(lambda s: s.internal, state, internal)
    return state
