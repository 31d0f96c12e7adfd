import jax
import pytest

# Entry points switch float64 on; the library never does on import.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")

import jaxmpm as jm  # noqa: E402

# One shared list: a new interpolator or transfer inherits every parametrised check.
INTERPOLATORS = {
    "spq": jm.SPQ(),
    "gimp": jm.GIMP(),
    "cpgimp": jm.GIMP(contiguous=True),
    "cpdi": jm.CPDI(),
    "mpq": jm.MPQ(),
}
TRANSFERS = {"flip": jm.FLIP(), "pic": jm.PIC(), "apic": jm.APIC()}


@pytest.fixture(params=list(INTERPOLATORS), ids=list(INTERPOLATORS))
def interpolator(request):
    return INTERPOLATORS[request.param]


@pytest.fixture(params=list(TRANSFERS), ids=list(TRANSFERS))
def transfer(request):
    return TRANSFERS[request.param]


def _memory_maps() -> int:
    try:
        with open("/proc/self/maps") as f:
            return sum(1 for _ in f)
    except OSError:  # not Linux: no such limit to watch
        return 0


@pytest.fixture(autouse=True)
def _release_compiled_programs():
    """Each compiled XLA CPU program holds ~265 memory maps, and Linux allows 65,530 per process
    (vm.max_map_count): past ~245 live programs, XLA's JIT segfaults while compiling the next one.
    The suite compiles more than that, so it drops JAX's caches when the process nears the limit."""
    yield
    if _memory_maps() > 40_000:
        jax.clear_caches()
