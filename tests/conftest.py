import os

# The suite compiles several hundred small programs and runs each for a moment, so compiling is most
# of its time. XLA's CPU backend at optimisation level 0, with its classic (non-MLIR) fusion emitters,
# compiles a reverse-mode run about 2.5 times faster (1.3 s -> 0.5 s measured) and halves the suite.
# Each program is compiled as one LLVM module (no split for parallel codegen: the two xdist workers
# already keep both cores busy): XLA compile time of the suite 309 s -> 242 s summed.
os.environ["XLA_FLAGS"] = " ".join(
    (
        os.environ.get("XLA_FLAGS", ""),
        "--xla_backend_optimization_level=0",
        "--xla_llvm_disable_expensive_passes=true",
        "--xla_cpu_use_fusion_emitters=false",
        "--xla_cpu_parallel_codegen_split_count=1",
    )
).strip()

import jax  # noqa: E402
import pytest  # noqa: E402

# Entry points switch float64 on; the library never does on import.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")

from helpers import INTERPOLATORS, TRANSFERS  # noqa: E402


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
