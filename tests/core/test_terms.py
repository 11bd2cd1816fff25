"""Terms of eq. 2.6 and the hourglass-free discretisation (core.terms, core.elements)."""

import numpy as np
import pytest

from inbetween_cases import rotation, sphere_field
from keyframe_implicit.core import Grid
from keyframe_implicit.core.base import elements
from keyframe_implicit.core.map import terms


def _batch(Y, h, weight=None):
    d = Y.shape[-1]
    w = np.ones(len(Y)) if weight is None else weight
    return terms.ElementBatch(Y, w, elements.quadrature(d, h, "gauss"), elements.quadrature(d, h, "centre"))


def _cells(d, h, E, rng, scale=0.15):
    """E reference cells (corner positions) with a random smooth-ish deformation."""
    X = elements.corners(d) * h
    A = np.eye(d) + scale * rng.normal(size=(E, d, d))
    return np.einsum("eij,cj->eci", A, X) + scale * h * rng.normal(size=(E, 2 ** d, d))


def test_gradient_operator_reproduces_affine_maps():
    for d in (2, 3):
        rng = np.random.default_rng(d)
        A, t = rng.normal(size=(d, d)), rng.normal(size=d)
        h = 0.37
        Y = (elements.corners(d) * h) @ A.T + t
        for rule in ("gauss", "centre"):
            q = elements.quadrature(d, h, rule)
            F = elements.deformation_gradient(Y[None], q.G)[0]
            assert np.allclose(F, A[None], atol=1e-12)
            assert np.isclose(q.weights.sum(), h ** d)


@pytest.mark.parametrize("d", [2, 3])
def test_deformation_gradient_and_gram_match_their_definitions(d):
    """F[e, q, i, a] = sum_c Y[e, c, i] G[q, a, c] for every rule and spacing (the operator
    is made once per G: a second spacing must not reuse the first one's), and gram(F) is
    F F^T, for random, non-affine cells."""
    rng = np.random.default_rng(10 + d)
    for h in (0.37, 0.05):
        Y = _cells(d, h, 50, rng, scale=0.4)
        for G in (elements.quadrature(d, h, "gauss").G, elements.quadrature(d, h, "centre").G,
                  np.concatenate([elements.quadrature(d, h, r).G for r in ("gauss", "centre")])):
            F = elements.deformation_gradient(Y, G)
            assert F.shape == (50, len(G), d, d) and F.flags.c_contiguous
            assert np.allclose(F, np.einsum("eci,qac->eqia", Y, G), rtol=1e-12, atol=1e-12)
            FFt = elements.gram(F)
            assert np.allclose(FFt, F @ F.swapaxes(-1, -2), rtol=1e-12, atol=1e-12)
            assert np.array_equal(FFt, FFt.swapaxes(-1, -2))


def test_heaviside_matches_eq_2_7_and_its_derivative():
    eps = 0.3
    assert terms.heaviside(-eps - 1e-9, eps) == 0.0
    assert terms.heaviside(eps + 1e-9, eps) == 1.0
    assert np.isclose(terms.heaviside(0.0, eps), 0.5)
    # continuous at +-eps (the corrected middle case -eps <= phi <= eps)
    assert np.isclose(terms.heaviside(-eps, eps), 0.0, atol=1e-12)
    assert np.isclose(terms.heaviside(eps, eps), 1.0, atol=1e-12)
    p = np.linspace(-2 * eps, 2 * eps, 41)
    fd = (terms.heaviside(p + 1e-6, eps) - terms.heaviside(p - 1e-6, eps)) / 2e-6
    assert np.allclose(terms.heaviside_derivative(p, eps), fd, atol=1e-5)


@pytest.mark.parametrize("d", [2, 3])
def test_rigid_motion_costs_nothing(d):
    h = 0.1
    R = rotation([1, 2, 3], 1.1) if d == 3 else np.array([[np.cos(1.1), -np.sin(1.1)],
                                                              [np.sin(1.1), np.cos(1.1)]])
    X = elements.corners(d) * h
    Y = np.stack([X @ R.T + k for k in range(4)])  # 4 translated copies
    b = _batch(Y, h)
    for fn in (terms.volume_term, terms.rigidity_term):
        tv = fn(b)
        assert tv.energy < 1e-28
        assert np.abs(tv.grad).max() < 1e-12


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("fn", [terms.volume_term, terms.rigidity_term])
def test_element_gradient_and_gauss_newton_hessian(d, fn):
    rng = np.random.default_rng(7)
    h = 0.2
    Y = _cells(d, h, 3, rng)
    w = np.array([1.0, 0.5, 2.0])
    b = _batch(Y, h, w)
    tv = fn(b)
    # gradient vs central differences of the energy
    fd = np.zeros_like(Y)
    step = 1e-6
    for idx in np.ndindex(Y.shape):
        Yp, Ym = Y.copy(), Y.copy()
        Yp[idx] += step
        Ym[idx] -= step
        fd[idx] = (fn(_batch(Yp, h, w), False).energy - fn(_batch(Ym, h, w), False).energy) / (2 * step)
    assert np.allclose(tv.grad, fd, rtol=1e-5, atol=1e-9)

    # Gauss-Newton blocks vs 2 J^T J with J from differences of an independent residual
    K = 2 ** d
    if fn is terms.volume_term:
        def residual(Yc, wq=b.centre.weights):
            F = elements.deformation_gradient(Yc, b.centre.G)
            return (np.sqrt(wq)[None, :] * (elements.determinant(F) - 1)).reshape(len(Yc), -1)
    else:
        def residual(Yc, wq=b.gauss.weights):
            F = elements.deformation_gradient(Yc, b.gauss.G)
            R = np.einsum("eqia,eqib->eqab", F, F) - np.eye(d)
            return (np.sqrt(wq)[None, :, None, None] * R).reshape(len(Yc), -1)
    for e in range(len(Y)):
        J = np.zeros((residual(Y[e:e + 1]).shape[1], K * d))
        for k in range(K * d):
            c, j = divmod(k, d)
            Yp, Ym = Y[e:e + 1].copy(), Y[e:e + 1].copy()
            Yp[0, c, j] += step
            Ym[0, c, j] -= step
            J[:, k] = (residual(Yp) - residual(Ym))[0] / (2 * step)
        want = 2 * w[e] * J.T @ J
        got = tv.hess[e].transpose(0, 2, 1, 3).reshape(K * d, K * d)  # (c, c', j, j') blocks
        assert np.allclose(got, want, rtol=1e-5, atol=1e-8 * np.abs(want).max())


def test_levelset_term_gradient_and_hessian():
    g = Grid((0.0, 0.0), 0.1, (12, 12))
    psi = sphere_field(g, 0.55, 0.3)
    rng = np.random.default_rng(3)
    y = 0.55 + rng.uniform(-0.4, 0.4, size=(40, 2))
    eps = 1.5 * g.spacing
    h_phi = terms.heaviside(rng.uniform(-0.3, 0.3, 40), eps)
    wts = rng.uniform(0.5, 1.0, 40)

    def nb(yy):
        return terms.NodeBatch(yy, wts, h_phi, psi, g, eps)

    tv = terms.levelset_term(nb(y))
    step = 1e-7
    fd = np.zeros_like(y)
    for idx in np.ndindex(y.shape):
        yp, ym = y.copy(), y.copy()
        yp[idx] += step
        ym[idx] -= step
        fd[idx] = (terms.levelset_term(nb(yp), False).energy - terms.levelset_term(nb(ym), False).energy) / (2 * step)
    # multilinear Psi has kinks at cell faces: compare where no point sits on one
    assert np.allclose(tv.grad, fd, rtol=1e-4, atol=1e-6)
    # GN block = 2 w J J^T with J = -H'(psi) grad psi: rank one, PSD, trace = 2 w |J|^2
    tr = np.trace(tv.hess, axis1=1, axis2=2)
    assert np.all(tr >= 0)
    assert np.allclose(np.linalg.det(tv.hess), 0.0, atol=1e-10)


def test_registry_names_the_three_terms_with_their_options():
    names = [(t.name, t.weight_option, t.kind) for t in terms.TERMS]
    assert names == [("volume", "volume_weight", "element"), ("rigidity", "rigidity_weight", "element"),
                     ("levelset", "levelset_weight", "node")]


@pytest.mark.parametrize("d", [2, 3])
def test_checkerboard_hourglass_raises_energy_but_rigid_motion_does_not(d):
    """The naive one-point cell (eq. 2.9-2.10) does not see the checkerboard; ours does."""
    n = 6
    h = 0.1
    g = Grid((0.0,) * d, h, (n,) * d)
    P = g.points()
    idx = np.indices(g.shape)
    sign = (-1.0) ** idx.sum(axis=0)
    R = rotation([1, 1, 0], 0.7) if d == 3 else np.array([[np.cos(0.7), -np.sin(0.7)],
                                                           [np.sin(0.7), np.cos(0.7)]])
    rigid = P @ R.T + 0.3
    delta = 0.05 * h
    checker = rigid + delta * sign[..., None] * np.eye(d)[0]
    cs = elements.corners(d)
    base = np.argwhere(np.ones((n - 1,) * d, bool))
    nodes = base[:, None, :] + cs[None]

    def energy(field, naive=False):
        Y = field[tuple(nodes[..., a] for a in range(d))]
        b = _batch(Y, h)
        if naive:
            b = terms.ElementBatch(Y, b.weight, b.centre, b.centre)  # rigidity at the centre only
        return terms.volume_term(b, False).energy + terms.rigidity_term(b, False).energy

    assert energy(rigid) < 1e-25
    e_checker = energy(checker)
    # quadratic in the amplitude, bounded away from zero: at least 0.1 (delta/h)^2 per cell volume
    assert e_checker > 0.1 * (delta / h) ** 2 * len(base) * h ** d
    # the thesis' naive discretisation (one F per cell) would not notice it at all
    assert energy(checker, naive=True) < 1e-3 * e_checker
