"""The benchmark's jaxmpm run with the gas's power law as ``**`` and as ``jaxmpm._util.power`` (float32:
``exp(p log J)``), the two alternating in one process: M particle-steps/s, best of 3 runs per round.

The ``**`` form is the adiabatic gas's pressure ``P0 J^-gamma - p_atm`` written with ``**``, put in
place of the library's for its rounds. In float64 a third form alternates with them: ``exp(-gamma
log J)`` with the vectorised logarithm of ``experiments/power_forms.py``. Also prints each form's
mean final F and, for each form, the largest difference of its final F from the library's in ulps
(of ``max(|F|, 1)``).
A run that breaks down stops the script with jaxmpm's message naming the step and the particle.

    python experiments/power_ab.py [--dtype f32] [--dim 1] [--n 1048576] [--rounds 2] [--interpolator spq]
"""

import argparse
import pathlib
import sys

import jax
from _entry import check_particles, positive

import jaxmpm as jm


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dtype", choices=("f32", "f64"), default="f32")
    parser.add_argument("--dim", type=int, choices=(1, 2, 3), default=1)
    parser.add_argument("--n", type=positive, default=1_048_576, help="particles (default 1,048,576)")
    parser.add_argument("--rounds", type=positive, default=2, help="rounds of each form (default 2)")
    parser.add_argument("--interpolator", default="spq", choices=list(jm.INTERPOLATORS))
    args = parser.parse_args(argv)
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
    check_particles(parser, args.n, args.dim)
    jax.config.update("jax_enable_x64", args.dtype == "f64")
    import jax.numpy as jnp

    from benchmarks.bench import _scene, steps_for
    from jaxmpm import materials

    library = materials.AdiabaticGas.pressure

    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
    from power_forms import log_vectorised

    def with_pow(self, J):
        return self.P0 * J ** (-self.gamma) - self.p_atm

    def with_vectorised_log(self, J):
        return self.P0 * jnp.exp(-self.gamma * log_vectorised(J)) - self.p_atm

    forms = [("**", with_pow), ("power", library)]
    if args.dtype == "f64":
        forms.append(("vec log", with_vectorised_log))
    steps = steps_for(args.n, 100)
    scene, dt = _scene(args.n, args.dim)
    speed, F_mean, F = {}, {}, {}
    for _ in range(args.rounds):
        for form, pressure in forms:
            materials.AdiabaticGas.pressure = pressure
            jax.clear_caches()
            best = float("inf")
            for _ in range(3):
                try:
                    sol, _, run_s = jm.simulate_timed(
                        scene, jm.INTERPOLATORS[args.interpolator](), dt=dt, steps=steps
                    )
                except jm.SimulationError as error:  # its speed and final F would mean nothing
                    sys.exit(f"{form}: {error}")
                best = min(best, run_s)
            speed.setdefault(form, []).append(round(args.n * steps / best / 1e6, 1))
            F_mean[form] = float(jnp.mean(sol.state.F))
            F[form] = sol.state.F
    materials.AdiabaticGas.pressure = library
    for form in speed:
        # in ulps of max(|F|, 1): F's zero off-diagonal entries in 2D and 3D would count in subnormals
        scale = jnp.spacing(jnp.maximum(jnp.abs(F["power"]), 1.0))
        ulps = float(jnp.max(jnp.abs(F[form] - F["power"]) / scale))
        print(
            f"{form:7s} M particle-steps/s by round: {speed[form]}, mean final F {F_mean[form]!r}, "
            f"final F within {ulps:.0f} ulps of the library's"
        )


if __name__ == "__main__":
    main()
