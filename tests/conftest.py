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
