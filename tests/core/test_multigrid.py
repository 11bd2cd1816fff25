"""Multigrid-preconditioned CG against a direct solve of the trajectory Laplacian."""

import numpy as np
import pytest
from scipy.sparse.linalg import splu

from keyframe_implicit.core import Cancelled, Grid
from keyframe_implicit.core.base.multigrid import BlockMultigrid, block_pcg
from keyframe_implicit.core.motion.trajectory import Trajectories


def _set_up(*args):
    """`Trajectories` with their Poisson problem built (`Trajectories.setup`)."""
    tr = Trajectories(*args)
    tr.setup()
    return tr


def _two_balls_bending(n=40):
    """A map of two separate balls, each bent differently: two components, no closed form."""
    grid = Grid((-1.0, -1.0, -1.0), 2.0 / (n - 1), (n, n, n))
    x = grid.points()
    left = np.linalg.norm(x - [-0.55, 0, 0], axis=-1) < 0.3
    right = np.linalg.norm(x - [0.55, 0, 0], axis=-1) < 0.25
    a = 1.2 * x[..., 0]
    y = np.stack([np.sin(a) / 1.2, x[..., 1] * (1 + 0.3 * x[..., 0] ** 2),
                  x[..., 2] + 0.2 * np.cos(2 * x[..., 1])], axis=-1)
    return grid, y, left | right


def _direct(L, rhs, comp):
    """L^+ rhs by a sparse LU with one node per component pinned at 0 (the former solve)."""
    pinned = np.zeros(L.shape[0], dtype=bool)
    pinned[np.unique(comp, return_index=True)[1]] = True
    free = np.flatnonzero(~pinned)
    x = np.zeros_like(rhs)
    x[free] = splu(L[free][:, free].tocsc()).solve(rhs[free])
    return x


def test_trajectories_agree_with_the_direct_solve_to_a_ten_thousandth_of_a_cell():
    grid, y, mat = _two_balls_bending()
    tr = _set_up(grid, y, mat)
    assert tr.stats["active_components"] == 2
    assert len(tr.stats["multigrid_levels"]) >= 3
    for s in (0.25, 0.5, 0.9):
        got = tr._poisson(s)
        rhs = tr._rhs(s)
        want = _direct(tr._L, rhs, tr._comp)
        diff = got - want
        # each component may differ by a translation only; `_poisson` fixes it afterwards
        for c in range(tr._ncomp):
            m = tr._comp == c
            diff[m] -= diff[m].mean(axis=0)
        assert np.abs(diff).max() < 1e-4 * grid.spacing


def test_right_hand_side_in_chunks_of_cells_is_the_whole_one(monkeypatch):
    """`Trajectories._rhs` makes its targets a chunk of cells at a time: B T of the
    whole T, however the cells are cut (here into chunks of 400 and one left over)."""
    from keyframe_implicit.core.motion import trajectory

    grid, y, mat = _two_balls_bending(24)
    tr = _set_up(grid, y, mat)
    assert tr._ncells > 800 and tr._ncells % 400
    whole = tr._B @ (grid.spacing * np.swapaxes(tr._cell_targets(0.3), 1, 2).reshape(-1, 3))
    monkeypatch.setattr(trajectory, "_TARGET_CHUNK", 400)
    np.testing.assert_allclose(tr._rhs(0.3), whole, rtol=0, atol=1e-15)
    assert np.abs(whole).max() > 1e-3 * grid.spacing  # not trivially zero


def test_preconditioner_makes_cg_iterations_independent_of_the_grid():
    its = []
    for n in (24, 48):
        grid, y, mat = _two_balls_bending(n)
        its.append(_set_up(grid, y, mat).stats["cg_iterations"][0])
    assert its[1] <= its[0] + 4, its


def test_warm_start_from_the_answer_takes_no_iteration():
    grid, y, mat = _two_balls_bending(24)
    tr = _set_up(grid, y, mat)
    rhs = tr._rhs(0.5)
    x, it = block_pcg(tr._L, rhs, tr._mg, tol=1e-10)
    assert it > 3
    _, again = block_pcg(tr._L, rhs, tr._mg, x, tol=1e-9)
    assert again == 0


def _off_by(tr, got, want):
    """Largest difference of two solutions up to each component's translation."""
    diff = got - want
    for c in range(tr._ncomp):
        m = tr._comp == c
        diff[m] -= diff[m].mean(axis=0)
    return np.abs(diff).max()


def test_a_time_solves_the_same_whatever_was_solved_before_it():
    """CG starts from the parabola through Y(0), Y(1/2), Y(1): closer to the answer than
    the line through the ends, and the same start (so the same answer, to the bit) for a
    time asked alone or after others, as a preview frame or a farm task asks it."""
    grid, y, mat = _two_balls_bending(24)
    after, alone = _set_up(grid, y, mat), _set_up(grid, y, mat)
    for s in (0.2, 0.3, 0.4):
        after._poisson(s)
    want, _ = block_pcg(alone._L, alone._rhs(0.7), alone._mg, tol=1e-12)
    ends = alone._anchors
    line = 0.3 * ends[0.0] + 0.7 * ends[1.0]
    assert _off_by(alone, alone._start(0.7), want) < 0.2 * _off_by(alone, line, want)
    assert np.array_equal(after._poisson(0.7), alone._poisson(0.7))
    assert np.array_equal(after.positions(0.35), alone.positions(0.35))


def test_cg_polls_cancel_every_iteration():
    grid, y, mat = _two_balls_bending(24)
    tr = _set_up(grid, y, mat)
    rhs = tr._rhs(0.5)
    calls = []

    def check():
        calls.append(1)
        if len(calls) == 3:
            raise Cancelled("stop")
    with pytest.raises(Cancelled):
        block_pcg(tr._L, rhs, tr._mg, tol=1e-12, check=check)
    assert len(calls) == 3
    calls.clear()
    with pytest.raises(Cancelled):
        BlockMultigrid(tr._L, np.stack(np.unravel_index(tr._nodes, grid.shape), 1),
                       coarse_size=10, check=check)


def test_coarsest_inverse_cuts_the_translations():
    """Constants span L's null space; a pseudo-inverse that keeps roundoff there stalls CG."""
    grid = Grid((-1.0, -1.0, -1.0), 2.0 / 95, (96, 96, 96))
    x = grid.points()
    mat = np.linalg.norm(x / [0.6, 0.45, 0.45], axis=-1) < 1
    tr = _set_up(grid, 1.1 * x, mat)
    one = np.ones(tr._mg.coarse.shape[0])
    assert np.abs(tr._mg.coarse @ one).max() < 1e-8 * np.abs(tr._mg.coarse).max()
    assert max(tr.stats["cg_iterations"]) < 30


@pytest.mark.parametrize("sweeps,coarse_sweeps", [(2, 1), (1, 2), (3, 3)])
def test_v_cycle_is_symmetric_whatever_the_sweeps(sweeps, coarse_sweeps):
    """CG needs a symmetric preconditioner: each level smooths as often after its coarse
    correction as before it (the first sweep being the Jacobi step from zero)."""
    grid, y, mat = _two_balls_bending(24)
    tr = _set_up(grid, y, mat)
    coords = np.stack(np.unravel_index(tr._nodes, grid.shape), 1)
    mg = BlockMultigrid(tr._L, coords, coarse_size=60, sweeps=sweeps, coarse_sweeps=coarse_sweeps)
    assert len(mg.levels) >= 2  # a coarse level smooths too
    rng = np.random.default_rng(0)
    r1, r2 = rng.standard_normal((2, tr._L.shape[0]))
    a, b = r2 @ mg(r1), r1 @ mg(r2)
    assert abs(a - b) < 1e-9 * abs(a)
    assert r1 @ mg(r1) > 0
