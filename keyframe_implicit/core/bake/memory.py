"""What a bake will cost in memory, known before any work.

`estimate_memory` predicts the peak resident memory of the whole bake on a grid (the
model is spelled out in its docstring; its constants are fitted to the peaks
`benchmarks/bench_scale.py` measured, `benchmarks/fit_memory.py` refits them), and
`check_memory` refuses a grid that would not fit, naming the largest that would.
"""

from __future__ import annotations

from ..base.grid import Grid

__all__ = ["MemoryLimitError", "estimate_memory", "check_memory", "largest_fitting", "megabytes"]


class MemoryLimitError(ValueError):
    """The requested grid would need more memory than allowed.

    Attributes
    ----------
    required : int
        Estimated peak bytes of the request.
    limit : int
        The allowed bytes.
    max_resolution : int or None
        Largest resolution (cells along the longest side) that fits, None if even
        the smallest does not.
    """

    def __init__(self, message, required, limit, max_resolution):
        super().__init__(message)
        self.required = int(required)
        self.limit = int(limit)
        self.max_resolution = max_resolution


# ---------------------------------------------------------------------------
# Peak resident set of a bake (VmHWM of the process running `animate`, plus its helper
# process's with processes=2), per process: an interpreter with numpy, scipy and
# scikit-image; per grid node the keyframes' distance grids, their spline coefficients,
# the maps, the in-between fields and the level-set transients; per active solver node
# the Gauss-Newton Hessian blocks (27 of 3 x 3) with their index tables, and the
# trajectories' multigrid. Fitted to the largest relative error (benchmarks/fit_memory.py)
# on the peaks benchmarks/bench_scale.py measured on its seven cases at 64 and 128 cells
# and two of them (bend, morph) at 256; tables in benchmarks/README.md.
# 2D: not measured; per active node scaled by the stencil (9 blocks of 2 x 2 against 27
# of 3 x 3).
_COPIES = 2
_PROCESS_BYTES = 106.9 * 2 ** 20
_NODE_BYTES = {2: 194.5, 3: 194.5}
_ACTIVE_BYTES = {2: 2285.3 * 36 / 243, 3: 2285.3}


def estimate_memory(grid: Grid, *, material_fraction=None, n_keyframes=2, margin_cells=3):
    """Estimated peak resident bytes of a bake on ``grid``, before any work.

    Model (N grid nodes, M active solver nodes):
    ``peak = 2 (c_process + c_node N + c_active M)``, with M = the material
    (``material_fraction * N``) plus the map's margin of ``margin_cells`` around it
    (a compact blob's surface ~ N^((d-1)/d)). Two of everything: the Blender bake runs
    in a worker and its helper process, each solving one of a segment's two maps and
    holding a copy of its in-betweens (`chain.animate_chain` with ``processes=2``); in
    one process the two maps are solved in two threads at once. The constants (module
    source) are fitted to measured peaks; benchmarks/bench_scale.py prints the estimate
    beside the measured peak.

    Parameters
    ----------
    grid : Grid
    material_fraction : float, optional
        Fraction of the grid inside the largest keyframe (0..1), e.g.
        ``np.mean(phi < 0)``; default 0.25 (`fit_grid` guesses it from the box).
    n_keyframes : int
        Distance grids held at once (the per-node part grows by 8 bytes per grid).
    margin_cells : float
        Width of the map's margin around the material the solver also works on.

    Returns
    -------
    dict
        ``nodes``, ``active_nodes``, ``process`` (the fixed part), ``grid_nodes`` and
        ``active`` (the parts per node and per active node, both copies together) and
        ``peak``, in bytes (ints).
    """
    if not isinstance(grid, Grid):
        raise ValueError(f"grid must be a keyframe_implicit.core.Grid, got {type(grid).__name__}.")
    f = 0.25 if material_fraction is None else float(material_fraction)
    if not 0.0 <= f <= 1.0:
        raise ValueError(f"material_fraction must lie in [0, 1], got {material_fraction}.")
    N, d = grid.size, grid.dim
    P = _COPIES
    # margin nodes around a compact blob holding f * N nodes: its surface ~ (f N)^((d-1)/d)
    surface = (f * N) ** ((d - 1) / d) * (4.84 if d == 3 else 3.55)  # sphere / disc
    M = min(N, f * N + 2 * margin_cells * surface)
    out = {
        "nodes": int(N),
        "active_nodes": int(M),
        "process": int(P * _PROCESS_BYTES),
        "grid_nodes": int(P * N * (_NODE_BYTES[d] + 8 * max(int(n_keyframes) - 2, 0))),
        "active": int(P * M * _ACTIVE_BYTES[d]),
    }
    out["peak"] = out["process"] + out["grid_nodes"] + out["active"]
    return out


def check_memory(grid: Grid, max_bytes, **memory_options):
    """Raise `MemoryLimitError` if `estimate_memory` (grid) exceeds ``max_bytes``.

    The message names the largest grid of the same box (resolution counted along
    the longest side without padding is unknown here, so nodes along the longest
    axis are given). Use ``fit_grid(..., max_bytes=...)`` to get a resolution.
    Returns the estimate otherwise.
    """
    est = estimate_memory(grid, **memory_options)
    if est["peak"] > max_bytes:
        longest = max(grid.shape)

        def shrunk(m):  # the grid shrunk uniformly to m nodes along its longest axis
            s = m / longest
            return Grid(grid.origin, grid.spacing / s,
                        tuple(max(2, int(round(n * s))) for n in grid.shape))

        fits = largest_fitting(shrunk, 2, longest - 1, max_bytes, **memory_options)
        shape = "x".join(str(n) for n in grid.shape)
        msg = (f"a {shape} grid needs about {megabytes(est['peak'])} but the limit is {megabytes(max_bytes)}; ")
        msg += ("even the smallest grid does not fit: raise the memory limit." if fits is None else
                f"the largest that fits has {fits} nodes along its longest axis: lower the resolution.")
        raise MemoryLimitError(msg, est["peak"], max_bytes, fits)
    return est


def largest_fitting(grid_of, low, high, max_bytes, **memory_options):
    """The largest size m in [low, high] whose grid ``grid_of(m)`` fits in ``max_bytes``
    (`estimate_memory`), or None: a binary search, the estimate growing with m."""
    fits = None
    while low <= high:
        m = (low + high) // 2
        if estimate_memory(grid_of(m), **memory_options)["peak"] <= max_bytes:
            fits, low = m, m + 1
        else:
            high = m - 1
    return fits


def megabytes(x):
    """``x`` bytes as the messages say them: "1,234 MB"."""
    return f"{x / 2 ** 20:,.0f} MB"
