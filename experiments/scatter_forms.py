"""How XLA's CPU backend prices the ways of writing the step's particle-to-grid sums.

Each form sums the same ``2 n`` weighted values (two nodes per particle, particles sorted as in a
1D body) onto ``n_nodes`` nodes, for three quantities (mass, momentum, force), inside a
``lax.scan`` so that dispatch does not count:

- ``node windows x3``: three scatters of ``n`` windows of two consecutive nodes (what ``Grid.scatter``
  does in 1D, given the stencil's first nodes);
- ``scalar x6``: six scalar scatters of ``n`` values (what the plain-JAX baseline does);
- ``flat x3``: three scalar scatters of ``2 n`` values (what ``Grid.scatter`` does without them);
- ``per column x3``: each of the three as two scatters, one per stencil column;
- ``window (2n, 3)``: one scatter of three-value rows;
- ``complex x2``: mass and momentum as the real and imaginary parts of one complex scatter;
- ``sorted hint``, ``segment_sum``: the flat form told that its indices are sorted.

Also the gathers of a 1D G2P: per node (``field[i]``, ``field[i + 1]``), as rows of a stacked
``(field[j], field[j + 1])`` array, and as windows of two nodes (what ``Grid.gather`` does in 1D).

    python experiments/scatter_forms.py [--n 262144,1048576] [--x64]

Prints milliseconds per step and nanoseconds per scattered value; compare rows within one run.
In isolation one scatter per stencil column is the cheapest form, yet inside the whole step it was
slower than the flat form (see the performance docs): measure forms in the step too.
"""

import argparse
import time

import jax


def forms(n_nodes):
    """The ways of writing the three particle-to-grid sums.

    Args:
        n_nodes: grid nodes.

    Returns:
        ``{name: f(i, w1, [mass, momentum, force] values) -> [three nodal arrays]}``.
    """
    import jax.numpy as jnp

    z = lambda *tail: jnp.zeros((n_nodes, *tail))  # noqa: E731

    def scalar6(i, w1, vals):
        w0 = 1 - w1
        return [z().at[i].add(w0 * v).at[i + 1].add(w1 * v) for v in vals]

    def flat3(i, w1, vals, **kw):
        idx = jnp.stack([i, i + 1], 1).reshape(-1)
        w = jnp.stack([1 - w1, w1], 1)
        return [z().at[idx].add((w * v[:, None]).reshape(-1), mode="drop", **kw) for v in vals]

    def per_column3(i, w1, vals):
        return [z().at[i].add((1 - w1) * v, mode="drop").at[i + 1].add(w1 * v, mode="drop") for v in vals]

    def window(i, w1, vals):
        idx = jnp.stack([i, i + 1], 1).reshape(-1)
        w = jnp.stack([1 - w1, w1], 1)
        rows = (w[:, :, None] * jnp.stack(vals, 1)[:, None, :]).reshape(-1, len(vals))
        out = z(len(vals)).at[idx].add(rows, mode="drop")
        return [out[:, k] for k in range(len(vals))]

    def complex2(i, w1, vals):
        idx = jnp.stack([i, i + 1], 1).reshape(-1)
        w = jnp.stack([1 - w1, w1], 1)
        mm = jax.lax.complex((w * vals[0][:, None]).reshape(-1), (w * vals[1][:, None]).reshape(-1))
        out = jnp.zeros(n_nodes, mm.dtype).at[idx].add(mm, mode="drop")
        force = z().at[idx].add((w * vals[2][:, None]).reshape(-1), mode="drop")
        return [out.real, out.imag, force]

    def sorted_hint(i, w1, vals):
        return flat3(i, w1, vals, indices_are_sorted=True)

    def segsum(i, w1, vals):
        idx = jnp.stack([i, i + 1], 1).reshape(-1)
        w = jnp.stack([1 - w1, w1], 1)
        return [
            jax.ops.segment_sum((w * v[:, None]).reshape(-1), idx, n_nodes, indices_are_sorted=True)
            for v in vals
        ]

    def node_windows3(i, w1, vals):  # what jaxmpm's 1D grid scatter does (Grid.scatter with base)
        w = jnp.stack([1 - w1, w1], 1)
        dims = jax.lax.ScatterDimensionNumbers((1,), (), (0,))
        mode = jax.lax.GatherScatterMode.FILL_OR_DROP
        return [
            jax.lax.scatter_add(jnp.zeros(n_nodes + 2), (i + 1)[:, None], w * v[:, None], dims, mode=mode)[
                1:-1
            ]
            for v in vals
        ]

    return {
        "node windows x3": node_windows3,
        "scalar x6": scalar6,
        "flat x3": flat3,
        "per column x3": per_column3,
        "window (2n, 3)": window,
        "complex x2": complex2,
        "sorted hint": sorted_hint,
        "segment_sum": segsum,
    }


def gathers():
    """The two ways of writing a 1D grid-to-particle gather.

    Returns:
        ``{name: f(i, w1, field) -> values at the particles}``.
    """
    import jax.numpy as jnp

    def per_node(i, w1, field):
        return (1 - w1) * field[i] + w1 * field[i + 1]

    def rows(i, w1, field):
        stacked = jnp.stack([field[:-1], field[1:]], 1)[i]
        return (1 - w1) * stacked[:, 0] + w1 * stacked[:, 1]

    def node_windows(i, w1, field):  # what jaxmpm's 1D grid gather does (Grid.gather with base)
        dims = jax.lax.GatherDimensionNumbers((1,), (), (0,))
        mode = jax.lax.GatherScatterMode.FILL_OR_DROP
        pair = jax.lax.gather(jnp.pad(field, 1), (i + 1)[:, None], dims, (2,), mode=mode, fill_value=0.0)
        return (1 - w1) * pair[:, 0] + w1 * pair[:, 1]

    return {"gather per node": per_node, "gather stacked rows": rows, "gather node windows": node_windows}


def time_form(fn, args, reps=30):
    """Seconds per call of ``fn`` inside a compiled ``lax.scan`` of ``reps`` calls (after a warm run).

    Args:
        fn: the form.
        args: its arguments (the second one is the array the scan perturbs).
        reps: calls per scan.

    Returns:
        Seconds per call.
    """

    def loop(*a):
        def body(c, _):
            out = fn(a[0], a[1] + c * 0, *a[2:])
            out = out if isinstance(out, list) else [out]
            return c + sum(o.sum() for o in out) * 0, None

        return jax.lax.scan(body, jax.numpy.zeros((), a[1].dtype), None, length=reps)[0]

    f = jax.jit(loop)
    jax.block_until_ready(f(*args))
    t0 = time.perf_counter()
    jax.block_until_ready(f(*args))
    return (time.perf_counter() - t0) / reps


def _sizes(text: str) -> list[int]:
    """``text``, comma-separated particle counts of at least 12 (the particles lie between nodes 5 and
    ``n / 2``), as a list (an ``argparse`` type)."""
    try:
        sizes = [int(s) for s in text.split(",")]
    except ValueError:
        sizes = []
    if not sizes or min(sizes) < 12:
        raise argparse.ArgumentTypeError(f"comma-separated particle counts >= 12, got {text!r}")
    return sizes


def main(argv: list[str] | None = None):
    """Time every form at each size of ``--n`` and print milliseconds and nanoseconds per value."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--n", type=_sizes, default="262144,1048576", help="particle counts, comma-separated (>= 12 each)"
    )
    p.add_argument("--x64", action="store_true")
    args = p.parse_args(argv)
    jax.config.update("jax_enable_x64", args.x64)
    import jax.numpy as jnp

    for n in args.n:
        n_nodes = n // 2 + n // 8 + 10
        key = jax.random.PRNGKey(0)
        x = jnp.sort(jax.random.uniform(key, (n,), minval=5.0, maxval=n // 2))
        i = jnp.floor(x).astype(jnp.int32)
        w1 = x - jnp.floor(x)
        vals = [jax.random.normal(jax.random.fold_in(key, k), (n,)) for k in range(3)]
        print(f"\nn = {n:,} particles, {n_nodes:,} nodes, {'float64' if args.x64 else 'float32'}")
        for name, fn in forms(n_nodes).items():
            s = time_form(lambda i_, w_, *v, fn=fn: fn(i_, w_, list(v)), (i, w1, *vals))
            print(f"  {name:20s} {s * 1e3:7.2f} ms   {s / (6 * n) * 1e9:5.2f} ns per value")
        field = jax.random.normal(key, (n_nodes,))
        for name, fn in gathers().items():
            s = time_form(fn, (i, w1, field))
            print(f"  {name:20s} {s * 1e3:7.2f} ms   {s / (2 * n) * 1e9:5.2f} ns per value")


if __name__ == "__main__":
    main()
