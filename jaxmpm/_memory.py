"""What a run needs in memory, estimated from its sizes before anything is built, and the check that
refuses a run that cannot fit.

The estimate counts float64 words: per particle, the state and body (``~20 + 10 dim^2``) and the
step's per-stencil-node arrays (``~6 dim`` words for each of the ``stencil_width^dim`` nodes a
particle's weights reach); per grid node, ``10 + 6 dim``; and the saved history. Measured peaks of
the forward run (resident memory, 1D to 3D, every interpolator) lie within about 25% of it.
Reverse mode stores more (see ``checkpoint`` in ``simulate``) and is not counted.
"""

import os

import jax

from ._step import Model

_WORD = 8  # bytes of a float64


def sizes(model: Model) -> tuple[int, int]:
    """The particle count (artificial particles included) and grid node count of a run.

    Args:
        model: the run.

    Returns:
        ``(particles, nodes)``.
    """
    scene = model.scene
    dim = scene.dim
    along = scene.cells * scene.ppc
    particles = along**dim
    if model.artificial_cells:
        grown = (scene.cells + 2 * model.artificial_cells) * scene.ppc
        particles = grown**dim  # the body's box grown at every face: an upper bound
    nodes = (scene.cells + 2 * scene.pad + 1) ** dim
    return particles, nodes


def run_bytes(model: Model, steps: int, saveat) -> int:
    """Estimated peak memory of one forward run, in bytes.

    Args:
        model: the run.
        steps: its step count (``max_steps`` for a run to an end time).
        saveat: what it saves (a ``SaveAt``); each saved field adds its size per saved step.

    Returns:
        The estimate in bytes.
    """
    dim = model.scene.dim
    particles, nodes = sizes(model)
    stencil = model.interpolator.stencil_width**dim
    words = particles * (20 + 10 * dim * dim + 6 * dim * stencil) + nodes * (10 + 6 * dim)
    if saveat.every is not None:
        per_particle = {"x": dim, "v": dim, "F": dim * dim, "sigma": dim * dim, "C": dim * dim}
        per_particle["corners"] = 2**dim * dim  # an upper bound: MPQ shares corners between neighbours
        per_particle["x_traction"] = dim
        saved = steps // saveat.every + 1
        words += saved * particles * sum(per_particle.get(f, 0) for f in saveat.fields)
    return _WORD * words


def available_bytes() -> int | None:
    """Memory the default device can still take, in bytes, or ``None`` where it cannot be read.

    On a CPU, the host's available memory (``MemAvailable`` of ``/proc/meminfo``, else free pages);
    on an accelerator, its memory limit less what is in use.

    Returns:
        Bytes, or ``None``.
    """
    device = jax.devices()[0]
    if device.platform != "cpu":
        try:
            stats = device.memory_stats() or {}
        except Exception:  # pragma: no cover - a backend without memory statistics
            return None
        if "bytes_limit" not in stats:
            return None
        return int(stats["bytes_limit"]) - int(stats.get("bytes_in_use", 0))
    return host_available_bytes()


def host_available_bytes() -> int | None:
    """The host's available memory in bytes (``MemAvailable`` of ``/proc/meminfo``, else free pages),
    or ``None`` where it cannot be read. Reads no device: JAX's backend is not started.

    Returns:
        Bytes, or ``None``.
    """
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not POSIX
        return None


def readable(nbytes: int | float) -> str:
    """A byte count in words: ``"3.2 GB"``.

    Args:
        nbytes: bytes.

    Returns:
        The count with a decimal unit.
    """
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if nbytes < 1000 or unit == "PB":
            return f"{nbytes:.3g} {unit}" if unit != "B" else f"{int(nbytes)} B"
        nbytes /= 1000
    raise AssertionError  # pragma: no cover


def check_lattice(cells, ppc, pad, dim) -> None:
    """Refuse, before the host builds it, a scene's lattice of particles that would not fit in the
    host's memory (a body of regions is laid out with NumPy when the scene is made).

    Args:
        cells, ppc, pad, dim: the scene's sizes (Python or NumPy integers).

    Raises:
        ValueError: the lattice's points and the grid's nodes need more than the host has, naming
            the sizes to reduce.
    """
    cells, ppc, pad, dim = int(cells), int(ppc), int(pad), int(dim)  # Python ints do not overflow
    points = (cells * ppc) ** dim
    nodes = (cells + 2 * pad + 1) ** dim
    nbytes = _WORD * (points * (dim + 6) + nodes)
    available = host_available_bytes()
    if available is not None and nbytes > available:
        raise ValueError(
            f"the scene (cells={cells}, ppc={ppc}, pad={pad}: {points:,} lattice points, {nodes:,} grid "
            f"nodes) needs about {readable(nbytes)} of memory to lay out, more than the "
            f"{readable(available)} available; reduce cells, ppc or pad"
        )


def check(nbytes: int, what: str, hint: str = "make it smaller") -> None:
    """Refuse, before anything is allocated, what would need more memory than the device has.

    Args:
        nbytes: the estimate (``run_bytes``, times the members of an ensemble).
        what: what needs it, in words, with the sizes that drive it (e.g. ``"the run (2,000,000,000
            particles, 1,000,000,021 grid nodes)"``).
        hint: what to change, ending the message.

    Raises:
        ValueError: ``nbytes`` exceeds the available memory.
    """
    available = available_bytes()
    if available is not None and nbytes > available:
        raise ValueError(
            f"{what} needs about {readable(nbytes)} of memory, more than the {readable(available)} "
            f"available on this {jax.devices()[0].platform.upper()}; {hint}"
        )


def check_run(model: Model, steps: int, saveat, members: int = 1) -> None:
    """``check`` for ``members`` runs of ``model`` side by side (an ensemble; 1 for a plain run).

    Args:
        model: the run.
        steps: its step count.
        saveat: what it saves.
        members: runs side by side.

    Raises:
        ValueError: they would not fit; the message names the particle and node counts.
    """
    particles, nodes = sizes(model)
    what = f"the run ({particles:,} particles, {nodes:,} grid nodes"
    what += f", {steps // saveat.every + 1:,} saved steps)" if saveat.every is not None else ")"
    hint = "reduce cells, ppc or pad"
    if saveat.every is not None:
        hint += ", or save less often"
    if members > 1:
        what = f"{members:,} members of {what}"
        hint += ", or run fewer members"
    check(members * run_bytes(model, steps, saveat), what, hint)
