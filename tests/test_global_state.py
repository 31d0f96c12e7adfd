"""Library code never changes global state: importing jaxmpm, any of its modules or its plotting
leaves float64, dtype promotion and matplotlib's backend as the user had them."""

import subprocess
import sys

import pytest

PROBE = """
import importlib, pkgutil, sys
import jax, matplotlib

def state():
    return (
        bool(jax.config.jax_enable_x64),
        str(jax.config.jax_numpy_dtype_promotion),
        repr(dict.__getitem__(matplotlib.rcParams, "backend")),  # read without resolving it
        "matplotlib.pyplot" in sys.modules and matplotlib.get_backend(),
    )

before = state()
import jaxmpm
names = [m.name for m in pkgutil.walk_packages(jaxmpm.__path__, "jaxmpm.") if not m.name.endswith("__main__")]
for name in names:
    importlib.import_module(name)
after = state()
print(len(names), before == after, before, after)
"""


@pytest.mark.slow
def test_importing_jaxmpm_leaves_global_configuration_alone():
    env = {"PATH": "", "JAX_PLATFORMS": "cpu"}  # no MPLBACKEND, no JAX_ENABLE_X64 from the test run
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    n, same, *states = out.stdout.split(" ", 2)
    assert int(n) >= 30  # every module of the package was imported
    assert same == "True", states


def test_lazy_submodules_are_attributes_of_the_package():
    """``jm.calibrate``, ``jm.plotting`` and ``jm.reference`` are imported on first use (they bring
    optax, diffrax and matplotlib), and each appears once in ``dir(jm)``."""
    import jaxmpm as jm

    for name in ("calibrate", "plotting", "reference"):
        assert getattr(jm, name).__name__ == f"jaxmpm.{name}"
        assert dir(jm).count(name) == 1
    assert "version" not in dir(jm) and "PackageNotFoundError" not in dir(jm)


def test_the_command_line_called_in_process_gives_back_the_callers_float_type(capsys):
    """``main`` switches float64 on for its command and back off on return: a notebook that calls it
    with float64 off keeps float32 (a scene it made before still runs)."""
    import jax
    from helpers import float32

    import jaxmpm as jm
    from jaxmpm.cli import main

    with float32():
        scene = jm.GasExpansion(cells=4)
        argv = "run gas-expansion cells=4 --interpolator mpq --dt 1e-5 --steps 2 --json".split()
        assert main(argv) == 0
        assert '"steps": 2' in capsys.readouterr().out
        assert jax.config.jax_enable_x64 is False
        assert jm.simulate(scene, jm.MPQ(), dt=1e-5, steps=2).state.x.dtype.name == "float32"
        assert main(["run", "no-such-scene"]) == 2  # and on a refusal
        assert jax.config.jax_enable_x64 is False
