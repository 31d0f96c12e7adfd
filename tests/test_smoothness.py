"""Measures of the smoothness of a radially expanding gas: radial velocity and its spread at a common
radius, the rotation of F, vorticity, and folded domains, checked on hand-made states with exact
answers and on a short run of the blast."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmpm as jm
from jaxmpm import metrics
from jaxmpm._util import corner_signs
from jaxmpm.particles import Body, parallelogram_corners, seed_box

TOL = 1e-12  # round-off, for exact cases

# Compiled once per shape, which on the test machine is faster than op by op, and shows each measure
# jit-able.
rotation_angle = jax.jit(metrics.rotation_angle)
polar_rotation = jax.jit(metrics.polar_rotation)
spurious_rotation = jax.jit(metrics.spurious_rotation)
vorticity = jax.jit(metrics.vorticity)
reference_radius = jax.jit(metrics.reference_radius)
radial_velocity = jax.jit(metrics.radial_velocity)
radial_bin = jax.jit(metrics.radial_bin, static_argnames="bins")
angular_spread = jax.jit(metrics.angular_spread, static_argnames=("bins", "threshold", "detrend"))
corner_jacobians = jax.jit(metrics.corner_jacobians)
folded = jax.jit(metrics.folded)
folded_domains = jax.jit(metrics.folded_domains)
implied_corners = jax.jit(metrics.implied_corners)
domain_corners = jax.jit(metrics.domain_corners)
parallelogram_corners = jax.jit(parallelogram_corners)


def make_state(x, v=None, F=None, C=None):
    x = jnp.asarray(x)
    n, d = x.shape
    return jm.State(
        t=jnp.zeros(()),
        step=jnp.zeros((), jnp.int32),
        x=x,
        v=jnp.zeros_like(x) if v is None else jnp.asarray(v),
        F=jnp.broadcast_to(jnp.eye(d), (n, d, d)) if F is None else jnp.asarray(F),
        sigma=jnp.zeros((n, d, d)),
        C=None if C is None else jnp.asarray(C),
        corners=None,
        x_traction=None,
        status=jnp.zeros((), jnp.int32),
        fail_step=jnp.full((), -1, jnp.int32),
        fail_particle=jnp.full((), -1, jnp.int32),
    )


def box(cells, ppc=1, h=1.0):
    return seed_box(tuple(cells), ppc, jnp.asarray(h), jnp.asarray(1.0))


def disk_body(dim, cells=8, ppc=1):
    """The particles of a ``cells^dim`` box within ``cells h / 2`` of its centre: a disk (sphere)."""
    b = box([cells] * dim, ppc)
    keep = np.linalg.norm(np.asarray(b.X) - cells / 2, axis=1) <= cells / 2
    sub = lambda a: a[jnp.asarray(keep)]
    return Body(
        X=sub(b.X),
        r0=sub(b.r0),
        m=sub(b.m),
        V0=sub(b.V0),
        X_corners=b.X_corners,
        corner_ids=sub(b.corner_ids),
        boundary=sub(b.boundary),
    ), np.full(dim, cells / 2)


def rot2(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def rot3(theta, axis):
    n = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


def spd(dim, seed):
    """Symmetric positive definite stretches with eigenvalues in [0.3, 3]."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(5):
        Q, _ = np.linalg.qr(rng.normal(size=(dim, dim)))
        A = Q @ np.diag(rng.uniform(0.3, 3.0, dim)) @ Q.T
        out.append(0.5 * (A + A.T))  # exactly symmetric
    return np.stack(out)


# rotation of F ------------------------------------------------------------------------------------


@pytest.mark.parametrize("theta", [0.3, -1.2, 2.9])
def test_rotation_angle_2d_of_rotation_times_stretch(theta):
    U = spd(2, 0)
    F = rot2(theta)[None] @ U
    angle = rotation_angle(make_state(np.zeros((5, 2)), F=F))
    np.testing.assert_allclose(angle, theta, rtol=0, atol=TOL)
    assert np.all(np.asarray(rotation_angle(make_state(np.zeros((5, 2)), F=U))) == 0.0)


@pytest.mark.parametrize("theta, axis", [(0.3, (0, 0, 1)), (1.2, (1, -2, 0.5)), (3.0, (-1, 1, 1))])
def test_rotation_angle_3d_of_rotation_times_stretch(theta, axis):
    U = spd(3, 1)
    F = rot3(theta, axis)[None] @ U
    angle = rotation_angle(make_state(np.zeros((5, 3)), F=F))
    np.testing.assert_allclose(angle, theta, rtol=0, atol=TOL)
    pure = rotation_angle(make_state(np.zeros((5, 3)), F=U))
    np.testing.assert_allclose(pure, 0.0, rtol=0, atol=TOL)


def test_polar_rotation_is_the_svd_polar_factor():
    rng = np.random.default_rng(2)
    F = rng.normal(size=(50, 3, 3))
    F[np.linalg.det(F) < 0] *= -1.0  # det F > 0
    W, _, Vt = np.linalg.svd(F)
    np.testing.assert_allclose(polar_rotation(jnp.asarray(F)), W @ Vt, rtol=0, atol=TOL)


def test_rotation_angle_3d_about_an_axis_is_the_2d_angle():
    F2 = rot2(-0.7)[None] @ spd(2, 3)
    F3 = np.zeros((5, 3, 3))
    F3[:, :2, :2], F3[:, 2, 2] = F2, 1.7
    a2 = rotation_angle(make_state(np.zeros((5, 2)), F=F2))
    a3 = rotation_angle(make_state(np.zeros((5, 3)), F=F3))
    np.testing.assert_allclose(a3, np.abs(a2), rtol=0, atol=TOL)


@pytest.mark.slow
@pytest.mark.parametrize("dim", [2, 3])
def test_spurious_rotation_and_its_gradient_at_identity_and_at_a_rotation(dim):
    body = box([2] * dim)
    state = make_state(body.X)
    U = np.concatenate([spd(dim, 4), spd(dim, 5)])[: body.n]

    def rms(F):
        return spurious_rotation(jm.State(**{**vars(state), "F": F}), body)["rms"]

    grad = jax.jit(jax.grad(rms))
    g = grad(state.F)  # F = I: rms 0, gradient 0 (not NaN)
    assert float(rms(state.F)) == 0.0 and np.all(np.asarray(g) == 0.0)

    def F_of(theta):  # rotation by theta about the last axis (3D), times the stretches U
        R = np.eye(dim)
        R[:2, :2] = rot2(theta)
        return R[None] @ U

    theta, eps = 0.4, 1e-6
    out = spurious_rotation(make_state(body.X, F=F_of(theta)), body)
    assert abs(float(out["max"]) - theta) < TOL and abs(float(out["rms"]) - theta) < TOL
    dR = np.zeros((dim, dim))
    dR[:2, :2] = rot2(theta + np.pi / 2)  # d R(theta) / d theta
    d_theta = float(np.sum(np.asarray(grad(jnp.asarray(F_of(theta)))) * (dR[None] @ U)))
    fd = (float(rms(jnp.asarray(F_of(theta + eps)))) - float(rms(jnp.asarray(F_of(theta - eps))))) / (2 * eps)
    assert abs(d_theta - 1.0) < 1e-11 and abs(d_theta - fd) < 1e-8  # rms = theta


def test_spurious_rotation_checks_the_particle_count():
    with pytest.raises(ValueError, match="the state has 4 particles and the body 8"):
        spurious_rotation(make_state(np.zeros((4, 2))), box([4, 2]))


# vorticity ----------------------------------------------------------------------------------------


def test_vorticity_of_a_spin_plus_a_stretch():
    S = spd(2, 5)
    W = np.array([[0.0, -0.25], [0.25, 0.0]])  # spin rate 0.25
    w2 = vorticity(make_state(np.zeros((5, 2)), C=S + W))
    np.testing.assert_allclose(w2, 0.5, rtol=0, atol=TOL)
    omega = np.array([0.1, -0.2, 0.3])
    K = np.array([[0, -omega[2], omega[1]], [omega[2], 0, -omega[0]], [-omega[1], omega[0], 0]])
    w3 = vorticity(make_state(np.zeros((5, 3)), C=spd(3, 6) + K))
    np.testing.assert_allclose(w3, 2 * np.linalg.norm(omega), rtol=0, atol=TOL)
    with pytest.raises(ValueError, match="only APIC carries"):
        vorticity(make_state(np.zeros((5, 2))))


# radial velocity and its spread -------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("dim", [2, 3])
def test_radial_velocity_of_a_uniform_expansion(dim):
    body, c = disk_body(dim)
    x = c + 1.3 * (np.asarray(body.X) - c)
    state = make_state(x, v=0.7 * (x - c), F=np.broadcast_to(1.3 * np.eye(dim), (body.n, dim, dim)))
    R = np.linalg.norm(np.asarray(body.X) - c, axis=1)
    np.testing.assert_allclose(reference_radius(body, c), R, rtol=TOL, atol=0)
    np.testing.assert_allclose(radial_velocity(state, body, c), 0.7 * 1.3 * R, rtol=TOL, atol=0)


def test_radial_velocity_at_the_centre_is_zero_with_a_finite_gradient():
    body = box([2, 1])
    c = np.asarray(body.X[0])
    state = make_state(body.X, v=np.ones((2, 2)))
    np.testing.assert_allclose(radial_velocity(state, body, c), [0.0, 1.0], rtol=0, atol=TOL)
    g = jax.jit(jax.grad(lambda x: jnp.sum(radial_velocity(make_state(x, v=np.ones((2, 2))), body, c))))(
        state.x
    )
    assert np.all(np.isfinite(g))


def numpy_bins(body, c, bins):
    R = np.linalg.norm(np.asarray(body.X) - c, axis=1)
    return R, np.minimum(np.floor(R / R.max() * bins), bins - 1).astype(int)


@pytest.mark.parametrize("dim, bins", [(2, 4), (2, 7), (3, 3)])
def test_angular_spread_of_a_uniform_expansion_is_the_spread_of_R_per_bin(dim, bins):
    body, c = disk_body(dim)
    x = c + 1.3 * (np.asarray(body.X) - c)
    state = make_state(x, v=0.7 * (x - c))
    R, k = numpy_bins(body, c, bins)
    np.testing.assert_array_equal(radial_bin(body, c, bins), k)
    full = np.array([np.any(k == b) for b in range(bins)])  # 2D, 7 bins: the first is empty
    assert full.all() == (bins != 7)
    want = np.array([np.std(R[k == b]) / np.mean(R[k == b]) if full[b] else np.nan for b in range(bins)])
    out = angular_spread(state, body, c, bins)
    np.testing.assert_array_equal(out["counted"], full)
    np.testing.assert_allclose(out["per_bin"], want, rtol=TOL, atol=TOL)  # NaN where empty
    assert abs(float(out["max"]) - np.nanmax(want)) < TOL
    assert abs(float(out["rms"]) - np.sqrt(np.nanmean(want**2))) < TOL


@pytest.mark.parametrize("dim", [2, 3])
def test_detrended_spread_takes_out_the_radial_variation(dim):
    """detrend=True: a v_r linear in R has no spread at all; a v_r quadratic in R has the spread of the
    residual of each bin's least-squares line; a non-radial part shows either way."""
    bins = 4
    body, c = disk_body(dim)
    R, k = numpy_bins(body, c, bins)
    e = np.asarray(body.X) - c
    e_r = e / np.linalg.norm(e, axis=1, keepdims=True)
    linear = angular_spread(make_state(body.X, v=(0.5 + 0.7 * R)[:, None] * e_r), body, c, bins, detrend=True)
    assert float(linear["max"]) < TOL
    vr = 0.5 + 0.3 * R**2
    quad = angular_spread(make_state(body.X, v=vr[:, None] * e_r), body, c, bins, detrend=True)
    want = []
    for b in range(bins):
        Rb, vb = R[k == b], vr[k == b]
        dR = Rb - Rb.mean()
        slope = np.sum(dR * vb) / np.sum(dR**2) if np.ptp(Rb) > 1e-9 else 0.0  # a bin of one radius
        resid = vb - vb.mean() - slope * dR
        want.append(np.sqrt(np.mean(resid**2)) / abs(np.mean(vb)))
    np.testing.assert_allclose(quad["per_bin"], want, rtol=1e-9, atol=TOL)
    swirl = np.zeros_like(e)
    swirl[:, 0], swirl[:, 1] = -e[:, 1], e[:, 0]  # tangential: no v_r
    tilted = (0.5 + 0.7 * R)[:, None] * e_r + 0.3 * e[:, :1] * e_r  # v_r depends on direction
    out = angular_spread(make_state(body.X, v=tilted + swirl), body, c, bins, detrend=True)
    assert float(out["max"]) > 0.05


@pytest.mark.parametrize("dim", [2, 3])
def test_angular_spread_of_a_radial_step_is_zero_with_a_finite_gradient(dim):
    bins = 4
    body, c = disk_body(dim)
    _, k = numpy_bins(body, c, bins)
    e = np.asarray(body.X) - c
    e_r = e / np.linalg.norm(e, axis=1, keepdims=True)
    g = np.array([1.0, 2.0, 3.0, 5.0])
    out = angular_spread(make_state(body.X, v=g[k, None] * e_r), body, c, bins)
    assert np.all(np.asarray(out["counted"]))
    assert np.abs(np.asarray(out["per_bin"])).max() < TOL and float(out["max"]) < TOL

    def rms(v):
        return angular_spread(make_state(body.X, v=v), body, c, bins)["rms"]

    assert np.all(np.isfinite(jax.jit(jax.grad(rms))(jnp.asarray(g[k, None] * e_r))))


def test_angular_spread_leaves_out_bins_at_rest():
    bins = 4
    body, c = disk_body(2)
    _, k = numpy_bins(body, c, bins)
    e = np.asarray(body.X) - c
    e_r = e / np.linalg.norm(e, axis=1, keepdims=True)
    for g0, counted in [(0.0, False), (0.5e-3 * 5, False), (2e-3 * 5, True)]:  # threshold 1e-3
        g = np.array([g0, 2.0, 3.0, 5.0])
        v = g[k, None] * e_r * (1 + 0.1 * (np.arange(body.n) % 2))[:, None]  # every other 10 % faster
        out = angular_spread(make_state(body.X, v=v), body, c, bins)
        np.testing.assert_array_equal(out["counted"], [counted, True, True, True])
        per_bin = np.asarray(out["per_bin"])
        assert np.isnan(per_bin[0]) != counted and np.all(per_bin[1:] > 0.01)
        assert abs(float(out["max"]) - np.nanmax(per_bin)) < TOL
        assert abs(float(out["rms"]) - np.sqrt(np.nanmean(per_bin**2))) < TOL
    nothing = angular_spread(make_state(body.X), body, c, bins)
    assert float(nothing["max"]) == 0.0 and float(nothing["rms"]) == 0.0
    with pytest.raises(ValueError, match="bins must be a positive integer"):
        angular_spread(make_state(body.X), body, c, 0)


# folded domains -----------------------------------------------------------------------------------


def numpy_corner_jacobians(corners, r0):
    """The multilinear map's Jacobian ``det(dx/dxi)`` at each corner of ``[-1, 1]^dim``, over
    ``prod r0``, from the shape functions' gradients."""
    n, nc, d = corners.shape
    s = corner_signs(d)
    out = np.zeros((n, nc))
    for c in range(nc):
        xi = s[c]
        dN = np.zeros((nc, d))  # dN_k / dxi_a at xi
        for kk in range(nc):
            for a in range(d):
                others = [(1 + s[kk, b] * xi[b]) / 2 for b in range(d) if b != a]
                dN[kk, a] = s[kk, a] / 2 * np.prod(others)
        J = np.einsum("nki,ka->nia", corners, dN)
        out[:, c] = np.linalg.det(J) / np.prod(r0, axis=1)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_reference_domains_have_unit_corner_jacobians_tracked_and_implied(dim):
    body = box([3, 2, 2][:dim], ppc=2, h=0.5)
    tracked = body.particle_corners(body.X_corners)
    implied = parallelogram_corners(body.r0, body.X, jnp.broadcast_to(jnp.eye(dim), (body.n, dim, dim)))
    np.testing.assert_allclose(tracked, implied, rtol=0, atol=TOL)  # one corner order for both
    for corners in (tracked, implied):
        np.testing.assert_allclose(corner_jacobians(corners, body), 1.0, rtol=0, atol=TOL)
        assert int(folded_domains(corners, body)) == 0


def test_corner_order_is_the_tensor_product_order():
    body = box([1, 1], h=2.0)  # one particle, centre (1, 1), r0 = 1
    c = np.asarray(body.particle_corners(body.X_corners))[0]
    np.testing.assert_array_equal(c, [[0, 0], [0, 2], [2, 0], [2, 2]])


def test_quadrilateral_with_a_corner_across_the_diagonal_is_folded():
    body = box([3, 1], h=2.0)  # three unit squares' particles, r0 = 1
    x = np.asarray(body.X)
    s = corner_signs(2)
    corners = x[:, None, :] + s[None]  # reference squares [-1, 1]^2 about each centre
    corners[1, 3] = x[1] + [-0.5, -0.5]  # (+,+) across the diagonal from (-,+) to (+,-)
    corners[2] = x[2] + s @ np.array([[1.0, 0.0], [0.3, 1.0]]).T  # mildly sheared
    J = np.asarray(corner_jacobians(jnp.asarray(corners), body))
    np.testing.assert_allclose(J[1], [1.0, 0.25, 0.25, -0.5], rtol=0, atol=TOL)  # by hand
    np.testing.assert_allclose(J, numpy_corner_jacobians(corners, np.asarray(body.r0)), rtol=0, atol=TOL)
    np.testing.assert_array_equal(folded(jnp.asarray(corners), body), [False, True, False])
    assert int(folded_domains(jnp.asarray(corners), body)) == 1


def test_inverted_parallelogram_is_folded():
    body = box([3, 1])
    F = np.stack([np.array([[1.0, 0.4], [0.1, 0.9]]), np.array([[0.2, 1.0], [1.0, 0.3]]), np.eye(2)])
    F[2, 1, 1] = 0.0  # det F = 0: degenerate, also folded
    corners = implied_corners(make_state(body.X, F=F), body)
    J = np.asarray(corner_jacobians(corners, body))
    np.testing.assert_allclose(J, np.linalg.det(F)[:, None] * np.ones((1, 4)), rtol=0, atol=TOL)
    np.testing.assert_array_equal(folded(corners, body), [False, True, True])


def test_hexahedron_with_a_corner_pushed_through_is_folded():
    body = box([3, 1, 1], h=2.0)  # r0 = 1
    x = np.asarray(body.X)
    s = corner_signs(3)
    corners = x[:, None, :] + s[None]
    corners[1, 7] = x[1] + [-0.5, -0.5, -0.5]  # (+,+,+) through the plane of its three neighbours
    corners[2] = x[2] + s @ np.array([[1.0, 0.2, 0.0], [0.0, 1.0, 0.3], [0.1, 0.0, 1.0]]).T
    J = np.asarray(corner_jacobians(jnp.asarray(corners), body))
    np.testing.assert_allclose(J, numpy_corner_jacobians(corners, np.asarray(body.r0)), rtol=0, atol=TOL)
    assert J[1, 7] < 0 and np.all(J[[0, 2]] > 0)
    np.testing.assert_array_equal(folded(jnp.asarray(corners), body), [False, True, False])
    assert int(folded_domains(jnp.asarray(corners), body)) == 1


@pytest.mark.parametrize("push, which", [(0.3, []), (0.5, [7]), (1.5, [1, 2, 3, 4, 5, 6, 7])])
def test_moving_a_tracked_corner_folds_the_particles_around_it(push, which):
    """Eight particles (edges 1) meet at a tracked corner, moved by ``push (1, 1, 1)``. The (+,+,+)
    particle's edges there are ``e_a - push (1, 1, 1)``, Jacobian ``1 - 3 push``: folded past 1/3
    (the corner crosses the plane of its three neighbours). The six mixed particles' least Jacobian
    is ``1 - push``: folded past 1. The (-,-,-) particle only grows."""
    body = box([1, 1, 1], ppc=2, h=2.0)  # 8 particles, r0 = 1/2, meeting at the corner (1, 1, 1)
    X_c = np.asarray(body.X_corners).copy()
    centre = int(np.flatnonzero(np.all(X_c == 1.0, axis=1))[0])
    X_c[centre] += push * np.array([1.0, 1.0, 1.0])
    corners = body.particle_corners(jnp.asarray(X_c))
    J = np.asarray(corner_jacobians(corners, body))
    np.testing.assert_allclose(
        J, numpy_corner_jacobians(np.asarray(corners), np.asarray(body.r0)), rtol=0, atol=TOL
    )
    assert abs(J[7, 0] - (1 - 3 * push)) < TOL and np.all(np.abs(J[1:7].min(axis=1) - (1 - push)) < TOL)
    np.testing.assert_array_equal(np.flatnonzero(folded(corners, body)), which)
    assert int(folded_domains(corners, body)) == len(which)


def test_folded_in_1d_is_a_nonpositive_length():
    body = box([3])
    corners = jnp.asarray([[0.0, 1.0], [2.0, 1.5], [2.0, 2.0]])[:, :, None]
    np.testing.assert_allclose(corner_jacobians(corners, body), [[1, 1], [-0.5, -0.5], [0, 0]])
    np.testing.assert_array_equal(folded(corners, body), [False, True, True])


def test_corner_jacobians_check_the_corner_count():
    with pytest.raises(ValueError, match="2\\^dim = 4 corners in 2D, got 3"):
        corner_jacobians(jnp.zeros((1, 3, 2)), box([1, 1]))


# a run ---------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_quarter_blast_is_symmetric_about_the_diagonal():
    """A quarter of the square charge is symmetric under swapping x and y: the mirror particle has
    the same radial velocity, the opposite rotation and vorticity, and the same corner Jacobians
    (corners (-,+) and (+,-) swapped)."""
    scene = jm.Blast(cells=4, ppc=2, pad=6)
    c0 = np.sqrt(1.4 * 1.5e5 / 1.5)
    sol = jm.simulate(scene, jm.MPQ(), dt=float(scene.h) / (4 * c0), steps=20, transfer=jm.APIC())
    state, body = sol.state, sol.body
    mirror = np.arange(body.n).reshape(8, 8).T.reshape(-1)
    c = np.zeros(2)
    vr = np.asarray(radial_velocity(state, body, c))
    angle = np.asarray(rotation_angle(state))
    w = np.asarray(vorticity(state))
    J = np.asarray(corner_jacobians(domain_corners(state, body), body))
    assert np.abs(angle).max() > 0.01  # not a radial motion: the charge is square
    assert np.abs(vr - vr[mirror]).max() <= TOL * np.abs(vr).max()
    assert np.abs(angle + angle[mirror]).max() <= TOL * np.abs(angle).max()
    assert np.abs(w + w[mirror]).max() <= TOL * np.abs(w).max()
    assert np.abs(J - J[mirror][:, [0, 2, 1, 3]]).max() <= TOL
    assert int(folded_domains(domain_corners(state, body), body)) == 0
    rot = spurious_rotation(state, body)
    assert float(rot["max"]) == pytest.approx(np.abs(angle).max(), rel=TOL)


def test_the_vtk_particle_fields_carry_the_rotation_and_the_smallest_corner_jacobian():
    """A rigid rotation by 0.3 rad: every particle's rotation is 0.3 and its corners' Jacobian 1; a
    particle whose F is inverted has a negative one."""
    body = box([2, 2], ppc=2)
    F = np.broadcast_to(rot2(0.3), (body.n, 2, 2)).copy()
    F[5] = np.diag([1.0, -0.5])
    fields = jm.vtk.particle_fields(make_state(body.X, F=F), body)
    np.testing.assert_allclose(np.delete(fields["rotation"], 5), 0.3, rtol=1e-14)
    np.testing.assert_allclose(np.delete(fields["corner_jacobian_min"], 5), 1.0, rtol=1e-14)
    assert fields["corner_jacobian_min"][5] == pytest.approx(-0.5, rel=1e-14)
