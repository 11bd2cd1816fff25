"""The coarse correction of the Gauss-Newton systems (`core/map/coarse.py`)."""

import numpy as np
import pytest

from inbetween_cases import nudged_spheres, sphere_to_ellipsoid, unit_grid
from keyframe_implicit.core import solve_map
from keyframe_implicit.core.map import solver, system
from keyframe_implicit.core.map.coarse import CoarseSpace
from keyframe_implicit.core.map.options import MapOptions


def _level(n, d):
    """A `system.MapSystem` with two feature patches (so some nodes are not free), its
    Hessian at a wavy map, and the grid index of its nodes."""
    g = unit_grid(d, n)
    phi_a, phi_b = nudged_spheres(g)
    fa = np.full((2, d), 0.5)
    fa[1, 0] = 0.75
    L = system.MapSystem(phi_a, phi_b, g, fa, fa + 0.02, 3, 0.1, 0.12, patch_rigidity=10.0)
    y = L.x + 0.02 * np.sin(7 * L.x)
    w = {"volume": 30.0, "rigidity": 1.0, "levelset": 10.0}
    _, _, _, Hs = L.evaluate(y, w, 512, True)
    coords = np.stack(np.unravel_index(L.active, g.shape), axis=-1)
    return L, Hs, coords


def _prolongation(space, n_free):
    P = np.zeros((n_free, space.n_aggregates))
    P[np.arange(n_free), space.agg_free] = 1.0
    return P


@pytest.mark.parametrize("d,n", [(2, 40), (3, 14)])
def test_coarse_operator_is_the_galerkin_product_over_the_free_nodes(d, n):
    L, Hs, coords = _level(n, d)
    free = L.cons.free_nodes
    assert 0 < len(free) < L.n  # the patches hold some nodes
    space = CoarseSpace(coords, L.bsr_indices.reshape(L.n, -1), free, unknowns=40 * d)
    assert space.side >= 2 and 1 < space.n_aggregates and d * space.n_aggregates <= 40 * d
    H = L.bsr(Hs).toarray().astype(float)
    sel = (free[:, None] * d + np.arange(d)).reshape(-1)
    Pn = np.kron(_prolongation(space, len(free)), np.eye(d))  # node-major, like the unknowns
    expect = Pn.T @ H[np.ix_(sel, sel)] @ Pn
    Ac = space.operator(Hs).toarray()
    np.testing.assert_allclose(Ac, expect, rtol=0, atol=1e-9 * np.abs(expect).max())
    # and the correction is P A_c^-1 P^T
    r = np.random.default_rng(1).normal(size=(len(free), d))
    got = space.correction(Hs)(r)
    np.testing.assert_allclose(got.reshape(-1), Pn @ np.linalg.solve(expect, Pn.T @ r.reshape(-1)),
                               rtol=1e-8, atol=1e-12)


def test_the_coarse_correction_cuts_the_iterations_of_a_gauss_newton_system():
    L, Hs, coords = _level(36, 3)
    cons, d = L.cons, L.d
    H = L.bsr(Hs)
    diag = Hs[:, L.centre_off].astype(float)
    rng = np.random.default_rng(2)
    b = cons.project(cons.reduce(rng.normal(size=(L.n, d))))

    def apply_A(z):
        return cons.reduce((H @ cons.expand(z).reshape(-1)).reshape(-1, d))

    def iterations(precond):
        x, it = solver._pcg(apply_A, b, precond, cons.project, 1e-6, 2000)
        assert np.linalg.norm(cons.project(b - apply_A(x))) <= 1e-6 * np.linalg.norm(b) * 1.01
        return it

    jacobi = cons.block_preconditioner(diag)
    space = CoarseSpace(coords, L.bsr_indices.reshape(L.n, -1), cons.free_nodes, 2000)
    two_level = solver._with_correction(jacobi, space.correction(Hs), cons.n_free, d)
    alone, both = iterations(jacobi), iterations(two_level)
    assert both < 0.6 * alone, (alone, both)


def test_a_map_solved_with_the_correction_matches_block_jacobi_in_fewer_iterations():
    """`solve_map` with the correction on every level (``coarse_space_from=0``): the same
    map up to CG's loose tolerance, in fewer CG iterations; off by default on a small grid."""
    g, phi_a, phi_b, fa, fb = sphere_to_ellipsoid(36)
    plain = solve_map(phi_a, phi_b, g, fa, fb)
    assert plain.stats["unknowns"] < MapOptions.coarse_space_from
    both = solve_map(phi_a, phi_b, g, fa, fb, coarse_space_from=0)
    assert both.stats["cg_iterations"] < 0.7 * plain.stats["cg_iterations"]
    assert abs(both.stats["energy"] / plain.stats["energy"] - 1) < 0.01
    assert both.stats["min_det"] >= 0.2 and both.stats["feature_residual_h"] < 1e-6
    material = phi_a < 0
    diff = np.linalg.norm(both.mapped[material] - plain.mapped[material], axis=-1).max()
    assert diff < 0.05 * g.spacing  # 0.004 h here
