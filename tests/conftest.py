import gc
import os
import shutil
import tempfile

# The suite compiles several hundred small programs and runs each for a moment, so compiling is most
# of its time. XLA's CPU backend at optimisation level 0, with its classic (non-MLIR) fusion emitters,
# compiles a reverse-mode run about 2.5 times faster (1.3 s -> 0.5 s measured) and halves the suite.
# Each program is compiled as one LLVM module (no split for parallel codegen: the xdist workers
# already keep every core busy): XLA compile time of the suite 309 s -> 242 s summed.
os.environ["XLA_FLAGS"] = " ".join(
    (
        os.environ.get("XLA_FLAGS", ""),
        "--xla_backend_optimization_level=0",
        "--xla_llvm_disable_expensive_passes=true",
        "--xla_cpu_use_fusion_emitters=false",
        "--xla_cpu_parallel_codegen_split_count=1",
    )
).strip()

# One compilation cache on disk for the whole run: both xdist workers and every process a test starts
# (command lines, notebooks, docs examples, multi-process runs) compile many of the same programs, and
# a program one of them compiled is read back by the others instead of compiled again (suite 569 s ->
# 499 s measured on 2 cores). It lives in a temporary folder of the run, made by the first pytest
# process (the controller; its workers and subprocesses inherit the variable) and removed by it at the
# end; a cache folder the caller set is used as it is and kept.
_OWN_CACHE = None
if "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    _OWN_CACHE = tempfile.mkdtemp(prefix="jaxmpm-tests-xla-cache-")
    os.environ["JAX_COMPILATION_CACHE_DIR"] = _OWN_CACHE
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")

import jax  # noqa: E402
import pytest  # noqa: E402

# Entry points switch float64 on; the library never does on import.
jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")
jax.config.update("jax_numpy_rank_promotion", "raise")

from helpers import INTERPOLATORS, TRANSFERS  # noqa: E402


def pytest_xdist_auto_num_workers(config):
    """``-n auto`` (the suite's default): one pytest-xdist worker more than the cores this process may
    use. A worker often waits (on a process a test started: a command line, a notebook, a docs example,
    a multi-process run), and the extra worker fills the cores meanwhile. Whole suite on 2 cores,
    alternating: 3 workers 484, 510, 495 and 486 s; 2 workers 522, 522 and 516 s; 4 workers 523 and
    480 s."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return cores + 1


# Python's cyclic garbage collector scans every tracked object in a full collection, and a worker's
# heap holds JAX, its caches and every traced program: full collections cost ~0.5 s each. What is
# imported by now lives until the end, so it is moved out of the collector's sight (gc.freeze), and
# the youngest generation is collected every 10,000 allocations instead of 700, so that far fewer
# objects survive into the older ones. Collector time per worker over the suite, measured with
# gc.callbacks: 18-21 s -> 8-9 s (full collections 31-33 -> 9).
gc.collect()
gc.freeze()
gc.set_threshold(10_000, 10, 10)


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


_TESTS_RUN = [0]


@pytest.fixture(autouse=True)
def _release_compiled_programs():
    """Each compiled XLA CPU program holds memory maps (57 for a small 1D run, measured; more for
    larger programs), and Linux allows 65,530 per process (vm.max_map_count): past that, XLA's JIT
    segfaults while compiling the next program. A worker compiles thousands, so it drops JAX's caches
    when the process nears the limit. The count is read every 10th test (reading /proc/self/maps costs
    ~10 ms at 9,000 maps); ten tests map far fewer than the 25,000 left below the limit."""
    yield
    _TESTS_RUN[0] += 1
    if _TESTS_RUN[0] % 10 == 0 and _memory_maps() > 40_000:
        jax.clear_caches()


def pytest_unconfigure(config):
    if _OWN_CACHE is not None and not hasattr(config, "workerinput"):  # the process that made it
        shutil.rmtree(_OWN_CACHE, ignore_errors=True)
