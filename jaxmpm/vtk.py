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

import contextlib
import os
import pathlib
import secrets
from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._checks import brief, check_bool, is_real
from ._files import check_folder, write_whole
from ._util import det
from .metrics import pressure


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


def _check_name(name) -> None:
    """Refuse a field name that a legacy VTK header cannot hold as one word."""
    if not isinstance(name, str) or not name or any(c == "%" or not "!" <= c <= "~" for c in name):
        raise ValueError(
            f"fields: the name {brief(name)} cannot be written in legacy VTK (its header is split on "
            "whitespace, and readers decode '%' escapes): a name is one word of printable ASCII "
            "(letters, digits, punctuation other than '%'), such as 'velocity' or 'internal.J_min'"
        )


def _check_fields(fields, n: int, where: str) -> dict[str, np.ndarray]:
    """``fields`` as float arrays of ``n`` values each, after checking their names and shapes.

    Args:
        fields: the point data given.
        n: the number of points.
        where: what the points are, for the message (``"particles"``, ``"nodes"``).

    Returns:
        ``{name: float array}``, in the order given.

    Raises:
        ValueError: ``fields`` is not a mapping, a name cannot be written (``_check_name``), or a
            value is not an array of real numbers of shape ``(n,)``, ``(n, 3)`` or ``(n, 9)``.
    """
    if not isinstance(fields, Mapping):
        raise ValueError(f"fields must be a dict of names to arrays, got {brief(fields)}")
    out = {}
    for name, a in fields.items():
        _check_name(name)
        if not is_real(a):
            raise ValueError(f"field {name!r} must be an array of real numbers, got {brief(a)}")
        a = np.asarray(a, dtype=float)
        if a.ndim == 0:
            raise ValueError(f"field {name!r} is one number, expected one value for each of the {n} {where}")
        if a.shape[0] != n:
            raise ValueError(
                f"field {name!r} has {a.shape[0]} values, expected one for each of the {n} {where}"
            )
        if not (a.ndim == 1 or (a.ndim == 2 and a.shape[1] in (3, 9))):
            raise ValueError(f"field {name!r}: shape {a.shape} is not (n,), (n, 3) or (n, 9)")
        out[name] = a
    return out


def _point_data(fields: Mapping[str, np.ndarray], n: int) -> bytes:
    """The ``POINT_DATA`` section of fields checked by ``_check_fields``."""
    parts = [f"POINT_DATA {n}\n".encode()]
    for name, a in fields.items():
        if a.ndim == 1:
            parts.append(f"SCALARS {name} double 1\nLOOKUP_TABLE default\n".encode())
        elif a.shape[1] == 3:
            parts.append(f"VECTORS {name} double\n".encode())
        else:
            parts.append(f"TENSORS {name} double\n".encode())
        parts.append(_be(a, ">f8") + b"\n")
    return b"".join(parts)


def _check_path(path) -> pathlib.Path:
    """``path`` as a ``pathlib.Path``, or a ``ValueError`` naming it."""
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise ValueError(f"path must be a file name (a str or os.PathLike), got {brief(path)}")
    return pathlib.Path(path)


def _check_positions(x) -> np.ndarray:
    """The positions ``x`` as a float array ``(n, dim)``, ``dim`` 1 to 3, or a ``ValueError``."""
    allowed = "x must be the positions, an array of shape (n, dim) with dim 1, 2 or 3"
    if not is_real(x):
        raise ValueError(f"{allowed}, got {brief(x)}")
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or not 1 <= x.shape[1] <= 3:
        raise ValueError(f"{allowed}, got shape {x.shape}")
    return x


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
        ValueError: ``path`` is not a file name, or is a folder; ``x`` is not an array of shape
            ``(n, dim)`` with ``dim`` 1 to 3; ``fields`` is not a dict, or a field has a name legacy
            VTK cannot hold (whitespace, ``%`` or other than printable ASCII), the wrong length or
            shape; or ``overwrite`` is not a bool.
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        FileNotFoundError: the folder of ``path`` does not exist (``NotADirectoryError``: it is a
            file).
    """
    path = _check_path(path)
    x = _check_positions(x)
    n = x.shape[0]
    fields = _check_fields({} if fields is None else fields, n, "particles")
    _refuse_existing([path], overwrite)
    check_folder(path)
    x = _pad_vectors(x)
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
        _point_data(fields, n),
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
        ValueError: ``path`` is not a file name, or is a folder; ``grid`` is not a ``jm.Grid`` of 1
            to 3 dimensions; ``fields`` is not a dict, or a field has a name legacy VTK cannot hold
            (whitespace, ``%`` or other than printable ASCII), the wrong length (not one value per
            node) or shape; or ``overwrite`` is not a bool.
        FileExistsError: ``path`` exists and ``overwrite`` is ``False``.
        FileNotFoundError: the folder of ``path`` does not exist (``NotADirectoryError``: it is a
            file).
    """
    from .grid import Grid

    path = _check_path(path)
    if not isinstance(grid, Grid) or not 1 <= grid.dim <= 3:
        raise ValueError(f"grid must be a jm.Grid of 1, 2 or 3 dimensions (scene.grid()), got {brief(grid)}")
    fields = _check_fields(fields, grid.n_nodes, "nodes")
    _refuse_existing([path], overwrite)
    check_folder(path)
    dim = grid.dim
    shape = list(grid.axes) + [1] * (3 - dim)
    origin = [float(o) for o in np.asarray(grid.x_min)] + [0.0] * (3 - dim)
    h = float(grid.h)
    spacing = [h] * dim + [1.0] * (3 - dim)
    if dim > 1:  # VTK runs x fastest; jaxmpm's flat order runs the last axis fastest
        fields = {
            k: v.reshape(tuple(grid.axes) + v.shape[1:])
            .transpose(tuple(reversed(range(dim))) + tuple(range(dim, v.ndim + dim - 1)))
            .reshape((grid.n_nodes,) + v.shape[1:])
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
    ``overwrite``, and a folder at one of them (``ValueError``) in any case."""
    check_bool("overwrite", overwrite)
    for path in paths:
        if path.is_dir():
            raise ValueError(f"path {path} is a folder, not a file: name the file to write")
        if not overwrite and os.path.lexists(path):
            raise _exists(path)


def _exists(path: pathlib.Path) -> FileExistsError:
    """The refusal of a file already at ``path``."""
    return FileExistsError(f"{path} already exists: pass overwrite=True to replace it")


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

    Raises:
        ValueError: ``model`` is not a ``Model``, or ``setup`` or ``state`` is not of its run (as
            ``jm.step`` checks them).
    """
    from . import _step

    _step.check_model(model)
    setup = eqx.filter_jit(_step.setup)(model) if setup is None else setup
    _step.check_belongs(model, setup, state)
    return _nodal_fields(model, setup, state)


def _nodal_fields(model, setup, state) -> dict[str, np.ndarray]:
    """``nodal_fields`` of a model, setup and state already checked (each frame of a series)."""
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
        ``rho`` (current density), ``p`` (``jaxmpm.metrics.pressure``: ``-tr(sigma) / dim``, the
        in-plane deviator of a metal with strength taken out), ``region`` (0 for a body of one
        region), the smoothness measures ``rotation`` (the angle of ``F``'s polar rotation, radians:
        ``jaxmpm.metrics.rotation_angle``) and ``corner_jacobian_min`` (the smallest Jacobian of the
        particle's domain at its corners, ``<= 0`` where it is folded or inverted:
        ``jaxmpm.metrics.corner_jacobians``), and where the run has them ``e`` and
        ``internal.<variable>``.
    """
    rotation, corner_jacobian_min = _smoothness(state, body)
    J = np.asarray(det(state.F))
    out = {
        "v": _pad_vectors(np.asarray(state.v)),
        "F": _pad_tensors(np.asarray(state.F), fill_identity=True),
        "sigma": _pad_tensors(np.asarray(state.sigma), fill_identity=False),
        "J": J,
        "X": _pad_vectors(np.asarray(body.X)),
        "rho": np.asarray(body.m) / (np.asarray(body.V0) * J),
        "p": np.asarray(pressure(state, allow_broken=True)),
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
    out_dir: str | os.PathLike,
    model,
    solution,
    *,
    overwrite: bool = False,
    allow_broken: bool = False,
) -> list[pathlib.Path]:
    """One particle file and one grid file per saved time of ``solution`` (run with a ``SaveAt`` that
    keeps ``x``, ``v``, ``F`` and ``sigma``, and ``corners`` for MPQ, ``C`` for APIC), plus
    ``particles.pvd`` and ``grid.pvd``, the collections ParaView opens as time series.

    Saved times past ``t_end`` in a run to an end time repeat the final state and are left out. The
    final state is the last frame, added when it falls between saves. A file already in ``out_dir``
    under one of the names written is refused unless ``overwrite``, and replaced with it; files of
    other names (the frames of an earlier, longer series among them) are left as they are. Every file
    is written under a temporary name, and the files are renamed into place once all are written, each
    file they replace first moved aside under a temporary name (``.NAME.<pid>-<hex>.old``) and deleted
    once the whole series is in place. A write or rename that fails (a full disk, Ctrl-C) removes what
    it wrote, moves the files it replaced back and leaves ``out_dir`` as it was (a folder it made is
    removed again); only a process killed outright between the renames, or a file system that fails
    to move a file back, leaves files under temporary names (the new ones ``.NAME.<pid>-<hex>.stage``,
    the replaced ones ``.old``). The model, the solution and the files already there are checked
    before anything is written.

    A run that broke down is refused unless ``allow_broken``. With it, the frames up to the last good
    state are written (saved times after the breakdown repeat that state and are left out; the last
    good state is the last frame), and both ``.pvd`` files say, in an XML comment after their
    declaration, at which step the run broke down and why (``solution.failure()``).

    The model is checked against what the solution records of its run: the body the model seeds
    (every field of ``jm.setup(model).body``: positions, domains, masses, volumes, regions), the
    parts of the state the run carries (APIC's ``C`` for an affine transfer, tracked ``corners``
    for MPQ, the energy ``e`` and the internal variables), and the initial state (``t = 0``, the
    first frame of the history): each saved field (``x``, ``v``, ``F``, ``sigma``, ...) against the
    model's own, up to round-off, which checks the scene's parameters that act at ``t = 0`` (its
    velocity, its material's stress). A solution does not record the interpolator (beyond whether
    it tracks corners), the transfer (FLIP and PIC alike), ``artificial_cells``, ``cfl_limit``,
    ``viscosity``, ``ordering``, ``volume_average``, the grid's padding, nor scene parameters that
    act only after ``t = 0`` (walls, tractions, body forces): those are not checked, and the grid
    files are the transfer of the model given.

    Args:
        out_dir: the directory to write to (made if missing).
        model: the run (a ``jm.Model``).
        solution: its ``Solution``.
        overwrite: replace the files already in ``out_dir`` under the names written (else refused).
        allow_broken: write the good frames of a run that broke down, marked as such in the ``.pvd``
            files (else such a run is refused).

    Returns:
        The paths written.

    Raises:
        ValueError: the solution has no history, or its history lacks a field the files need; it
            holds a batch (an ensemble's); it broke down and ``allow_broken`` is ``False``; the
            model is not the solution's run (as far as the solution records it, above); its
            internal variables have names legacy VTK cannot hold; ``out_dir`` is not a folder's name
            (empty, or not a path), is a file or a link to nothing or lies under one, or a folder
            is there under a name to write; ``model``
            is not a ``Model`` or ``solution`` not a ``Solution``; or ``overwrite`` or
            ``allow_broken`` is not a bool.
        FileExistsError: a file to write is already in ``out_dir`` and ``overwrite`` is ``False``.
    """
    check_bool("overwrite", overwrite)
    check_bool("allow_broken", allow_broken)
    if not isinstance(out_dir, (str, os.PathLike)) or not os.fspath(out_dir):
        raise ValueError(f"out_dir must be a folder's name (a str or os.PathLike), got {brief(out_dir)}")
    from ._simulate import Solution
    from ._step import check_model

    check_model(model)
    if not isinstance(solution, Solution):
        raise ValueError(
            f"solution must be the Solution of a run (jm.simulate(..., saveat=jm.SaveAt(every=k))), got "
            f"{type(solution).__name__ if isinstance(solution, eqx.Module) else brief(solution)}"
        )
    if solution.history is None:
        raise ValueError(
            "write_series needs a solution with a history: simulate(..., saveat=SaveAt(every=k))"
        )
    if solution.state.x.ndim != 2:
        raise ValueError(
            f"write_series writes one run, and this solution holds a batch (x of shape "
            f"{tuple(solution.state.x.shape)}): write each member (Ensemble.member(i))"
        )
    failure = solution.failure()
    if failure is not None and not allow_broken:
        raise ValueError(
            f"write_series writes a finished run, and this one broke down at step {failure['step']} "
            f"({' and '.join(failure['quantities'])}): its state is the last good one, at step "
            f"{int(solution.state.step)} (t = {float(solution.state.t):.6g}). Pass allow_broken=True to "
            "write its good frames, marked as a breakdown in the .pvd files"
        )
    from ._step import initial_state, setup

    prepared = eqx.filter_jit(setup)(model)  # once for the series: the grid and the body do not change
    _check_same_run(model, prepared, solution)
    needed = ["x", "v", "F", "sigma"]
    needed += ["corners"] if model.interpolator.tracks_corners else []
    needed += ["C"] if model.transfer.affine else []
    needed += ["e"] if solution.state.e is not None else []
    needed += [f"internal.{k}" for k in solution.state.internal or {}]
    missing = [f for f in needed if f not in solution.history]
    if missing:
        raise ValueError(f"the saved history lacks {missing}: add them to SaveAt(fields=...)")
    for k in solution.state.internal or {}:
        _check_name(f"internal.{k}")
    _check_initial_state(solution, eqx.filter_jit(initial_state)(model, prepared))
    ts = np.asarray(solution.ts)
    t_last = float(solution.state.t)
    keep = []  # saved times up to the final state's, each once (a run to t_end, or a broken run,
    for i, t in enumerate(ts):  # saves its final state again at every save that follows)
        if t <= t_last * (1 + 1e-12) and (not keep or t > ts[keep[-1]]):
            keep.append(i)
    frames = [(ts[i], _state_at(solution, i)) for i in keep]
    if not keep or t_last > ts[keep[-1]] * (1 + 1e-12):
        frames.append((t_last, solution.state))
    out = pathlib.Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {out_dir} is a file, not a folder")
    if out.is_symlink() and not out.exists():
        raise ValueError(f"out_dir {out_dir} is a link to nothing ({os.readlink(out)}), not a folder")
    above = next((p for p in out.parents if p.exists() or p.is_symlink()), None)
    if above is not None and not above.is_dir():
        raise ValueError(f"out_dir {out_dir}: {above} is a file (or a link to nothing), not a folder")
    names = [f"{kind}_{frame:05d}.vtk" for frame in range(len(frames)) for kind in ("particles", "grid")]
    _refuse_existing([out / name for name in names + ["particles.pvd", "grid.pvd"]], overwrite)
    made = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    tag = f"{os.getpid()}-{secrets.token_hex(4)}"
    staged: list[tuple[pathlib.Path, pathlib.Path]] = []  # (written under a temporary name, its name)
    ours: dict[pathlib.Path, tuple[int, int]] = {}  # a name to place: the identity of the file written for it
    aside: dict[pathlib.Path, pathlib.Path] = {}  # a file replaced: where it waits until the series is in

    def stage(name: str) -> pathlib.Path:
        staged.append((out / f".{name}.{tag}.stage", out / name))
        return staged[-1][0]

    try:
        entries = {"particles": [], "grid": []}
        for frame, (t, state) in enumerate(frames):
            fields = particle_fields(state, solution.body)
            p, g = f"particles_{frame:05d}.vtk", f"grid_{frame:05d}.vtk"
            write_particles(stage(p), state.x, fields)
            write_grid(stage(g), prepared.grid, _nodal_fields(model, prepared, state))
            entries["particles"].append((t, p))
            entries["grid"].append((t, g))
        for kind, items in entries.items():
            lines = ['<?xml version="1.0"?>']
            lines += [] if failure is None else [_breakdown_comment(failure, solution.state)]
            lines += ['<VTKFile type="Collection" version="0.1">', "<Collection>"]
            lines += [f'<DataSet timestep="{float(t)!r}" file="{name}"/>' for t, name in items]
            lines += ["</Collection>", "</VTKFile>", ""]
            _write(stage(f"{kind}.pvd"), "\n".join(lines).encode())
        for tmp, path in staged:  # every file is written: now into place, the .pvd files last
            ours[path] = _identity(tmp)  # (known before the rename: an undo finds the file by it)
            if overwrite and os.path.lexists(path):
                aside[path] = out / f".{path.name}.{tag}.old"
                os.replace(path, aside[path])
            _place(tmp, path, overwrite)
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        _undo(ours, aside)
        if made:
            with contextlib.suppress(OSError):  # not empty: it holds what someone else put there
                out.rmdir()
        raise
    for old in aside.values():  # the whole series is in place: the files it replaced go
        with contextlib.suppress(OSError):
            old.unlink()
    return [path for _, path in staged]


def _identity(path: pathlib.Path) -> tuple[int, int]:
    """The device and inode of the file at ``path`` (a rename or a hard link keeps them)."""
    st = os.lstat(path)
    return st.st_dev, st.st_ino


def _undo(ours: dict[pathlib.Path, tuple[int, int]], aside: dict[pathlib.Path, pathlib.Path]) -> None:
    """Take back the renames of an unfinished ``write_series``: each file it put in place is removed,
    and each file moved aside goes back under its name (over the new one, in one rename). Each step
    is tried whatever the others do; a file that cannot be moved back stays under its temporary name.

    Args:
        ours: a name written: the identity (``_identity``) of the file written for it.
        aside: a file that was there: the temporary name it was moved to (it may not have been yet).
    """
    for path, identity in ours.items():
        with contextlib.suppress(OSError):
            if path in aside and os.path.lexists(aside[path]):
                os.replace(aside[path], path)
            elif os.path.lexists(path) and _identity(path) == identity:
                path.unlink()


def _place(tmp: pathlib.Path, path: pathlib.Path, overwrite: bool) -> None:
    """Rename the written file ``tmp`` to ``path``; without ``overwrite``, never over a file there
    (a hard link fails on one; where the file system has none, checked just before the rename)."""
    if overwrite:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path)
    except FileExistsError:
        raise _exists(path) from None
    except OSError:  # no hard links here (FAT, some network file systems)
        if os.path.lexists(path):
            raise _exists(path) from None
        os.replace(tmp, path)
        return
    tmp.unlink()


def _breakdown_comment(failure: dict, state) -> str:
    """The XML comment of a ``.pvd`` file that says the series ends at a breakdown."""
    who = "the run itself" if failure["particle"] < 0 else f"first at particle {failure['particle']}"
    text = (
        f"jaxmpm: the run broke down at step {failure['step']} ({' and '.join(failure['quantities'])}; "
        f"{who}): the last frame is its last good state, step "
        f"{int(state.step)}, t = {float(state.t)!r}, not the end of the run"
    )
    return f"<!-- {text.replace('--', '- -')} -->"


def _differs(a, b) -> bool:
    """Whether two arrays differ in shape or beyond round-off (4096 ulps of their scale)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        return True
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(b.dtype, np.floating)):
        return not np.array_equal(a, b)
    eps = max(np.finfo(d).eps for d in (a.dtype, b.dtype) if np.issubdtype(d, np.floating))
    finite = np.abs(b[np.isfinite(b)])
    scale = float(np.max(finite)) if finite.size else 0.0
    return not np.allclose(a, b, rtol=4096 * eps, atol=4096 * eps * scale, equal_nan=True)


def _check_same_run(model, prepared, solution) -> None:
    """Refuse a model whose body or carried state parts are not those of the solution's run."""
    X, X_model = np.asarray(solution.body.X), np.asarray(prepared.body.X)
    if X.shape != X_model.shape:
        raise ValueError(
            f"the model is not the solution's run: its body has {X_model.shape[0]} particles in "
            f"{X_model.shape[1]}D, the solution's {X.shape[0]} in {X.shape[1]}D"
        )
    for name in ("X", "r0", "m", "V0", "X_corners", "corner_ids", "boundary", "region"):
        mine, theirs = getattr(prepared.body, name), getattr(solution.body, name)
        if (mine is None) != (theirs is None) or (mine is not None and _differs(mine, theirs)):
            raise ValueError(
                f"the model is not the solution's run: the body it seeds differs in {name} (Body.{name}: "
                "another scene, or other scene parameters)"
            )
    state = solution.state
    carried = (
        ("C", model.transfer.affine, f"its transfer {type(model.transfer).__name__}"),
        (
            "corners",
            model.interpolator.tracks_corners,
            f"its interpolator {type(model.interpolator).__name__}",
        ),
    )
    for name, needs, what in carried:
        if needs != (getattr(state, name) is not None):
            has = "carries" if needs else "does not carry"
            ran = "did not" if needs else "did"
            raise ValueError(
                f"the model is not the solution's run: {what} {has} {name}, and the solution's run {ran}"
            )


def _check_initial_state(solution, init) -> None:
    """Refuse a model whose initial state differs from the first frame (``t = 0``) of the history."""
    from ._simulate import STATE_FIELDS, save_fields

    state = solution.state
    if (init.e is None) != (state.e is None):
        has = "has" if init.e is not None else "has no"
        raise ValueError(
            f"the model is not the solution's run: its material {has} an energy equation (e), and the "
            f"solution's run {'did not' if init.e is not None else 'did'}"
        )
    if sorted(init.internal or {}) != sorted(state.internal or {}):
        raise ValueError(
            f"the model is not the solution's run: its internal variables are {sorted(init.internal or {})}, "
            f"the solution's {sorted(state.internal or {})}"
        )
    if float(np.asarray(solution.ts)[0]) != 0.0:  # a history that does not start at t = 0
        return
    for name, value in save_fields(init, STATE_FIELDS).items():
        if name in solution.history and _differs(value, solution.history[name][0]):
            raise ValueError(
                f"the model is not the solution's run: its initial {name} differs from the solution's "
                "(the first frame, t = 0): other scene parameters, or another scene"
            )


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
