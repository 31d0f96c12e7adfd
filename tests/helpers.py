"""Shared test helpers: the one list of every interpolator and transfer that parametrised checks
run over, so a new interpolator or transfer inherits every check; and the check of a usage error."""

import contextlib
import inspect

import jax

import jaxmpm as jm
from jaxmpm.cli import main

BACKEND_COMPILE = "/jax/core/compile/backend_compile_duration"
TRACE = "/jax/core/compile/jaxpr_trace_duration"

INTERPOLATORS = {name: make() for name, make in jm.INTERPOLATORS.items()}
TRANSFERS = {name: make() for name, make in jm.TRANSFERS.items()}


@contextlib.contextmanager
def monitored(*events: str):
    """Collect the JAX monitoring events named (default: each backend compilation) while the block
    runs: JAX reports every trace and every compilation to its listeners."""
    events = events or (BACKEND_COMPILE,)
    seen = []

    def listen(event, duration, **kwargs):
        if event in events:
            seen.append(event)

    jax.monitoring.register_event_duration_secs_listener(listen)
    try:
        yield seen
    finally:
        jax.monitoring.unregister_event_duration_listener(listen)


@contextlib.contextmanager
def float32():
    """Run the block with float64 off (JAX's default, what a user who does not switch it on gets), then
    restore the suite's setting."""
    x64 = bool(jax.config.jax_enable_x64)
    jax.config.update("jax_enable_x64", False)
    try:
        yield
    finally:
        jax.config.update("jax_enable_x64", x64)


def usage(capsys, argv, match):
    """Run ``jaxmpm argv``: exit status 2, nothing on stdout, one line on stderr with ``match``."""
    rc = main(argv)
    captured = capsys.readouterr()
    assert rc == 2, (argv, captured.err)
    assert "Traceback" not in captured.err and captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, (argv, captured.err)
    assert lines[0].startswith("jaxmpm: error:") and match in lines[0], lines[0]
    return lines[0]


def calibration_case():
    """A gas-slab fit of ``gamma`` and ``P0`` with four starts, the last of which breaks down (its slab
    expands off the grid at once): synthetic data from the truth ``gamma = 1.4, P0 = 3e5`` with 1%
    noise. For the calibration across devices and processes.

    Returns:
        ``(scene, t, data, starts, dt)``.
    """
    import numpy as np

    slab = dict(cells=16, h=1 / 16, pad=96)
    truth = jm.GasSlab(gamma=1.4, P0=3.0e5, **slab)
    t = np.linspace(0.0, 12e-3, 61)
    dt = 0.2 * float(truth.h) / float(np.sqrt(1.4 * 3.0e5 / float(truth.rho0)))
    x = np.asarray(jm.calibrate.trajectory(truth, jm.CPDI(), t, dt=dt))
    data = x * (1 + 0.01 * np.random.default_rng(0).standard_normal(x.size))
    starts = [
        dict(gamma=1.82, P0=2.1e5),
        dict(gamma=1.6, P0=3.6e5),
        dict(gamma=1.3, P0=2.8e5),
        dict(gamma=1.1, P0=3.9e5),
    ]
    return jm.GasSlab(**slab), t, data, starts, dt


def raw(fn):
    """``fn`` without the suite's runtime type checks of its annotations (what a user runs)."""
    return inspect.unwrap(fn)
