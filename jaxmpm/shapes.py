"""Shape functions of the background grid (1D linear hats) and their GIMP averages.

The hat of node i is ``S_i(x) = max(0, 1 - |x - x_i| / h)`` (Sulsky, Chen & Schreyer 1994). Every
function here takes the normalised coordinate ``xi = (x - x_i) / h`` so that it is independent of the
grid; the slope with respect to ``x`` is the slope with respect to ``xi`` divided by ``h``.
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


def hat(xi: Float[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
    """Linear hat ``max(0, 1 - |xi|)``.

    Args:
        xi: normalised coordinates ``(x - x_i) / h``.

    Returns:
        The hat at ``xi``.
    """
    return jnp.maximum(0.0, 1.0 - jnp.abs(xi))


def hat_integral(xi: Float[ArrayLike, "*shape"]) -> Float[Array, "*shape"]:
    """Antiderivative ``int_{-inf}^{xi} hat(s) ds`` of the hat, rising from 0 at -1 to 1 at +1.

    Used for the GIMP weight, the hat averaged over a particle domain (Bardenhagen & Kober 2004,
    eq. 29 specialised to a 1D top-hat particle characteristic function).

    Args:
        xi: normalised coordinates ``(x - x_i) / h``.

    Returns:
        The antiderivative at ``xi``.
    """
    left = 0.5 * jnp.square(1.0 + xi)
    right = 1.0 - 0.5 * jnp.square(1.0 - xi)
    inside = jnp.where(xi < 0.0, left, right)
    return jnp.where(xi <= -1.0, 0.0, jnp.where(xi >= 1.0, 1.0, inside))
