"""What a solve of the volume map returns (`solver.solve_map`), kept apart from the solver
so that a process which only reads solved maps (a farm's later tasks) need not import it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..base.grid import Grid

if TYPE_CHECKING:  # read by type checkers only: tear needs the solver's hierarchy
    from .tear import Tear

__all__ = ["MapResult"]


@dataclass
class MapResult:
    """Result of `solve_map`.

    mapped : ndarray, grid.shape + (d,)
        y(x) for every node (the smooth extension outside ``region``).
    stats : dict
        ``iterations`` (finest level), ``levels`` (per-level dicts), ``history``
        (per finest-level iteration: energy and each term), ``terms`` (final
        value of each weighted term), ``max_abs_det_minus_1``, ``min_det``
        (material cells, all quadrature points), ``feature_residual``
        (world units) and ``feature_residual_h`` (in grid spacings),
        ``seconds`` (per stage), ``active_nodes``, ``unknowns``,
        ``patch_features`` / ``hard_features`` (constraint kinds).
    grid : `Grid`
    region : bool array (grid.shape), the solved nodes of the finest level.
    material : bool array (grid.shape), phi_a < 0.
    components : int array (grid.shape), labels of A's material components.
    tear : `tear.Tear` or None
        The pieces of A's torn components and the crack between them, where the map
        spreads a component of A over several of B (`tear.find_tear`).
    parts : int array (grid.shape) or None
        The part of every node where A's components go to different components of B
        (`parts.part_labels`): the map tears between parts, and so do its trajectories.
    """

    mapped: np.ndarray
    stats: dict[str, Any]
    grid: Grid
    region: np.ndarray
    material: np.ndarray
    components: np.ndarray | None = field(default=None)

    tear: Tear | None = field(default=None)
    parts: np.ndarray | None = field(default=None)
