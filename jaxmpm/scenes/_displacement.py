"""Scenes that move as a prescribed displacement, held to it by a body force (the method of
manufactured solutions)."""

import abc

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._base import AbstractScene, check_point


class AbstractDisplacementScene(AbstractScene):
    """A scene moving as a prescribed displacement ``u(X, t)``, held to it by a body force.

    From ``u`` (the abstract method ``displacement``) autodiff gives ``F = I + du/dX``, ``v =
    du/dt``, ``a = d2u/dt2`` and the body force that makes ``u`` exact, ``b = a - (1 / rho0) Div_X P``
    with the first Piola stress ``P = _flux(X, t)`` (the balance of linear momentum in the reference
    configuration; the method of manufactured solutions of Wallstedt & Guilkey, J. Comput. Phys.
    227, 2008). Concrete scenes implement ``displacement`` and ``_flux`` and the rest of
    ``AbstractScene``; ``initial_velocity``, ``body_force`` and ``exact`` are implemented here.
    """

    @abc.abstractmethod
    def displacement(self, X: Float[ArrayLike, " dim"], t: Float[ArrayLike, ""]) -> Float[Array, " dim"]:
        """The prescribed displacement.

        Args:
            X: reference position of one material point.
            t: time.

        Returns:
            ``u(X, t)``.
        """

    @abc.abstractmethod
    def _flux(self, X: Float[ArrayLike, " dim"], t: Float[ArrayLike, ""]) -> Float[Array, "dim dim"]:
        """The first Piola stress at ``(X, t)``, whose divergence the body force balances."""

    def _F(self, X, t):
        return jnp.eye(X.shape[0], dtype=X.dtype) + jax.jacfwd(self.displacement)(X, t)

    def _velocity(self, X, t):
        return jax.jacfwd(self.displacement, argnums=1)(X, t)

    def initial_velocity(self, X):
        return self._velocity(X, jnp.zeros((), X.dtype))

    def body_force(self, X: Float[ArrayLike, " dim"], t: Float[ArrayLike, ""]) -> Float[Array, " dim"]:
        """The body force per unit mass that makes ``displacement`` exact.

        Args:
            X: reference position of one material point.
            t: time.

        Returns:
            ``b = a - (1 / rho0) Div_X P``.
        """
        a = jax.jacfwd(self._velocity, argnums=1)(X, t)
        div = jnp.einsum("abb->a", jax.jacfwd(self._flux)(X, t))  # d P_aB / dX_B
        return a - div / self.rho0

    def exact(self, X: Float[ArrayLike, " dim"], t: Float[ArrayLike, ""]) -> dict[str, Array]:
        """The exact fields of one material point.

        Args:
            X: reference position.
            t: time.

        Returns:
            ``dict(x, v, F, sigma)``: ``x = X + u``, ``v = du/dt``, ``F = I + du/dX`` and the
            material's Cauchy stress at that ``F``.

        Raises:
            ValueError: ``X`` is not of shape ``(dim,)``.
        """
        X = check_point(X, self.dim)
        F = self._F(X, t)
        return dict(
            x=X + self.displacement(X, t),
            v=self._velocity(X, t),
            F=F,
            sigma=self.material().stress(F),
        )
