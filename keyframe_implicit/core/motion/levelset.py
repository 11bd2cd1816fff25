"""In-between level sets (thesis section 3.2, eq. 3.2-3.4; docs/method.md, sections 6 and 8).

Two transports, one per keyframe (default, ``transport="two-sided"``)
----------------------------------------------------------------------
Keyframe A's field Phi is carried forward along A's as-rigid-as-possible
trajectories (the map A -> B, `trajectory.Trajectories`), and keyframe B's
field Psi backward along B's (the map B -> A), each from its own region only
(`transport.Transport`). At time s the two are blended at fixed grid nodes z,
in the spirit of the warp-and-blend of Cohen-Or, Levin and Solomovici (1998):

    L_s(z) = (1 - s) Phi_s(z) + s Psi_s(z),
    Phi_s(x_A(s)) = Phi(x),   Psi_s(x_B(1 - s)) = Psi(x),

with x_A(t), x_B(t) the node paths of A and B (material a map tears fades on
the way: `transport.Transport.carry`). In a chain the paths carry its
`spline.Bend`, so the motion flows through the keyframes (docs/method.md,
section 12). Both transported fields are truncated at one value w > 0, the smallest value either field has on the border of its
region (a few cells around the material). Where a transport does not reach
z, z lies beyond that border of the moved keyframe, so its value is w: "not
reached" and "far outside" agree, the blend is continuous where one
transport's region ends, and far from both keyframes L_s = w, never drifting
to zero. Neither transport hands depth from one keyframe to the empty space
of the other (the swelling of the one-sided form below in merges). Each
in-between is then shifted by the iso-value that keeps its volume on the
linear path between the keyframes' (`isovolume`). The ends are the keyframes
themselves: L_0 = Phi, L_1 = Psi.

The backward map is solved like the forward one with the feature pairs
swapped (`inbetween`), or, with `Inbetween.from_map`, given, or else
obtained by inverting the forward map (`invert_map`).

The thesis's one-sided form (``transport="one-sided"``)
-------------------------------------------------------
Only A's nodes move, each carrying v_s(x) = (1 - s) Phi(x) + s Psi(y(x))
(eq. 3.4, weights normalised). Kept for comparison: an empty-space node of
A's margin that maps deep into B carries B's depth, so gaps fill with
material long before the parts arrive, and B's material outside the image of
A's region appears only at s = 1. ``resample="idw"`` (one-sided only)
replaces the inverse lookup by the thesis's inverse-distance weights
(eq. 3.2-3.3), w = 1 / (r^2 + eps^2), over the moved nodes within
``idw_radius`` cells of each grid node. Measurements of every form:
benchmarks/README.md.
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..base.elements import inverse
from ..base.grid import Grid
from ..base.sampling import sample
from .finepaths import FinePaths, material_mass, on_motion_grid, same_width
from .isovolume import component_iso_values, volume_iso_value
from .options import MotionOptions
from .components import ComponentVolumes, component_labels
from .spline import start_velocity
from .band import band_depth, touches_surface
from .tension import fill_creases, meeting_reach
from ..surface.extract import enclosed_volume
from .trajectory import Trajectories
from .transport import Transport

if TYPE_CHECKING:
    from collections.abc import Callable

    from numpy.typing import ArrayLike

    from .spline import Bend

__all__ = ["Inbetween", "Recipe", "SeenFromB", "invert_map", "idw_resample", "map_agreement",
           "back_map", "path_start_velocity"]

_CACHED_FIELDS = 2  # in-between fields kept (each as large as the grid)
#: The surface tension's filling eases in over this much of s from each keyframe, so the
#: frames next to a keyframe continue it (`tension.fill_creases`' weight).
_TENSION_EASE = 0.15


def idw_resample(grid: Grid, positions: np.ndarray, values: np.ndarray, *, fill: float,
                 radius: float = MotionOptions.idw_radius,
                 eps: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Thesis eq. 3.2-3.3: inverse-distance weights 1 / (r^2 + eps^2) of nearby moved nodes.

    ``radius`` and ``eps`` are in cells. Grid nodes with no moved node within
    ``radius`` get ``fill``. Returns the field and a mask of the nodes reached, both of grid.shape.
    """
    h = grid.spacing
    tree = cKDTree(positions)
    z = grid.points().reshape(-1, grid.dim)
    k = 4 * 2 ** grid.dim
    dist, idx = tree.query(z, k=k, distance_upper_bound=radius * h, workers=-1)
    valid = np.isfinite(dist)
    idx = np.where(valid, idx, 0)
    w = np.where(valid, 1.0 / (dist ** 2 + (eps * h) ** 2), 0.0)
    wsum = w.sum(axis=1)
    covered = wsum > 0
    out = np.full(z.shape[0], float(fill))
    out[covered] = (w[covered] * values[idx[covered]]).sum(axis=1) / wsum[covered]
    return out.reshape(grid.shape), covered.reshape(grid.shape)


def invert_map(grid: Grid, forward: Transport) -> np.ndarray:
    """The map B -> A as the inverse of the map A -> B (``forward``'s trajectories at t = 1).

    Every node z in the image of A's region gets the source x with y(x) = z
    (the inverse lookup of the moved cells); nodes outside that image take
    the displacement of the nearest node inside it. Where the forward map
    folds, several sources share one z and the first found is kept.

    Returns
    -------
    ndarray, grid.shape + (d,)
    """
    d = grid.dim
    target, source = forward.sources(1.0)
    back = np.full((grid.size, d), np.nan)
    back[target] = grid.to_world(source)
    reached = ~np.isnan(back[:, 0])
    if not reached.any():
        raise ValueError("the map sends keyframe A's region outside the grid; "
                         "it cannot be inverted.")
    disp = back - grid.points().reshape(-1, d)
    _, idx = ndimage.distance_transform_edt(~reached.reshape(grid.shape), return_indices=True)
    nearest = np.ravel_multi_index(tuple(idx), grid.shape).reshape(-1)
    return (grid.points().reshape(-1, d) + disp[nearest]).reshape(grid.shape + (d,))


class Inbetween:
    """In-between frames of one keyframe pair: level sets and trajectories at any s in [0, 1].

    Build with `Inbetween.from_map` (maps you already have) or `inbetween`
    (solves the maps first).

    Attributes
    ----------
    grid : Grid
    mapped : ndarray, grid.shape + (d,)
        The map A -> B, y(x).
    mapped_back : ndarray or None
        The map B -> A (two-sided transport).
    trajectories : Trajectories
        Paths of A's nodes (A -> B); `trajectory` interpolates them.
    outside_value : float
        The value wherever no transport reaches (world units, > 0).
    threads : int
        2 (default): the two transports carry each level set in two threads, for a
        process with two cores to itself; 1: one after the other, for a process that
        shares the machine with another doing the same (`chain.FrameSplit`), where a
        second thread only competes with it.
    stats : dict
        Figures of the maps (when solved here), the trajectories and the
        level sets (timings in seconds, coverage, map agreement).
    """

    def __init__(self, phi_a: np.ndarray, phi_b: np.ndarray, grid: Grid, forward: Transport,
                 backward: Transport | None = None, *, options: MotionOptions | None = None,
                 stats: dict[str, Any] | None = None, map_result: object = None,
                 map_result_back: object = None) -> None:
        self.grid = grid
        self.phi_a = phi_a
        self.phi_b = phi_b
        self.forward = forward
        self.backward = backward
        self.trajectories = forward.trajectories
        self.transport = "one-sided" if backward is None else "two-sided"
        self.options = MotionOptions() if options is None else options
        self.keep_volume = self.options.keep_volume and backward is not None
        self._end_volumes = None
        self._components = None  # `components.ComponentVolumes`, made when first needed
        self.map_result = map_result
        self.map_result_back = map_result_back
        self.outside_value = forward.truncation  # both transports share it (from_map)
        self.threads = 2
        self.stats = dict(stats or {})
        self.stats.setdefault("levelset_seconds", 0.0)
        self.stats.setdefault("levelset_calls", 0)
        self.stats["transport"] = self.transport
        self.stats["trajectory"] = forward.trajectories.stats
        if backward is not None:
            self.stats["trajectory_back"] = backward.trajectories.stats
            tension = self.options.surface_tension
            forward.band_depth = backward.band_depth = band_depth(
                self.options.band_cells, grid, tension,
                tension > 0 and (forward.parts or backward.parts))
            self.stats["map_agreement_h"] = map_agreement(grid, forward.trajectories,
                                                          backward.trajectories, phi_a < 0)
        self._coef_b = None  # Psi's spline coefficients, for the one-sided form
        self._cache = {}

    # ------------------------------------------------------------------
    @classmethod
    def from_map(cls, phi_a: ArrayLike, phi_b: ArrayLike, grid: Grid, mapped: ArrayLike, *,
                 mapped_back: ArrayLike | None = None, material: np.ndarray | None = None,
                 components: np.ndarray | None = None, motion_grid: Grid | None = None,
                 bends: tuple[Bend | None, Bend | None] | None = None,
                 cracks: tuple[np.ndarray | None, np.ndarray | None] | None = None,
                 parts: tuple[np.ndarray | None, np.ndarray | None] | None = None,
                 options: MotionOptions | None = None, stats: dict[str, Any] | None = None,
                 map_result: object = None, map_result_back: object = None,
                 cancel: Callable[[], bool] | None = None, **keywords: Any) -> Inbetween:
        """In-betweens from given maps.

        Parameters
        ----------
        phi_a, phi_b : ndarray, grid.shape
            Signed distance grids of keyframes A and B (negative inside).
        grid : Grid
        mapped : ndarray, (motion_grid or grid).shape + (d,)
            The map A -> B, y(x) for every node (world units).
        mapped_back : ndarray, like ``mapped``, optional
            The map B -> A (two-sided transport); `invert_map` of ``mapped``
            when omitted.
        material : bool ndarray, optional
            A's material on the maps' grid; ``phi_a < 0`` there when omitted.
        components : int ndarray, optional
            Labels of A's material components (see `Trajectories`).
        motion_grid : Grid, optional
            The coarser grid the maps are given on, covering ``grid``'s box: the
            trajectories are solved there and read at ``grid``'s nodes
            (`finepaths.FinePaths`). None: the maps are on ``grid``.
        bends : (`spline.Bend`, `spline.Bend` or None), optional
            The Hermite corrections of the forward paths (on A's nodes) and the backward
            ones (on B's), on the maps' grid, that carry the velocity through the
            keyframes of a chain (`spline.chain_bends`); None: the straight timing.
        cracks : (bool ndarray or None, bool ndarray or None), optional
            The cells of the maps' grid where the forward and the backward map tear
            (`map.tear.Tear.crack`): the transport along that map leaves them out, so the
            pieces part with empty space between them.
        parts : (int ndarray or None, int ndarray or None), optional
            The parts of the maps' grid's nodes that the forward and the backward map
            keep apart (`map.result.MapResult.parts`): their trajectories tear there too.
        options : `options.MotionOptions`, optional
            All settings at once: how the bake passes them. Give them so or as keywords,
            not both.
        stats, map_result, map_result_back : optional
            Figures and results of the maps' solves, kept with the in-betweens.
        cancel : callable() -> bool, optional
            Polled by the trajectory solves and the transports, here and in every
            later `levelset` call; `progress.Cancelled` is raised once it returns True.
        **keywords
            Any field of `options.MotionOptions`: ``transport``, ``keep_volume``,
            ``trajectory_method``, ``trajectory_margin_cells``,
            ``trajectory_margin_weight``, ``resample``, ``idw_radius``,
            ``newton_steps``, ``interpolation`` (its docstring has their defaults): the
            form for callers outside the bake.
        """
        unknown = set(keywords) - MotionOptions.names()
        if unknown:
            raise TypeError(f"Inbetween.from_map got unexpected options {sorted(unknown)}.")
        if options is None:
            options = MotionOptions(**keywords)
        elif keywords:
            raise TypeError(f"Inbetween.from_map takes options= or keywords, not both; got "
                            f"options and {sorted(keywords)}.")
        if not isinstance(grid, Grid):
            raise ValueError("grid must be a keyframe_implicit.core.Grid.")
        phi_a = grid.check_field(phi_a, "phi_a")
        phi_b = grid.check_field(phi_b, "phi_b")
        mapped = np.asarray(mapped, dtype=float)
        if not np.any(phi_b < 0):
            raise ValueError("phi_b has no node inside (< 0): keyframe B is empty on this grid.")
        t0 = time.perf_counter()
        paths = _Paths(grid, motion_grid, options, cancel)
        if material is None:
            material = paths.on_motion(phi_a) < 0
        forward, backward = _transports(phi_a, phi_b, paths, mapped, mapped_back, material,
                                        components, options, cancel, bends or (None, None),
                                        cracks or (None, None), parts or (None, None))
        st = dict(stats or {}, trajectory_setup_seconds=time.perf_counter() - t0)
        out = cls(phi_a, phi_b, grid, forward, backward, options=options, stats=st,
                  map_result=map_result, map_result_back=map_result_back)
        out._recipe = Recipe((phi_a, phi_b, grid, mapped), dict(
            mapped_back=mapped_back, material=material, components=components,
            motion_grid=motion_grid, bends=bends, cracks=cracks, parts=parts, options=options))
        return out

    @property
    def mapped(self) -> np.ndarray:
        """The map A -> B on the surface grid, grid.shape + (d,)."""
        return self.forward.trajectories.mapped

    @property
    def mapped_back(self) -> np.ndarray | None:
        """The map B -> A on the surface grid (None for the one-sided transport)."""
        return None if self.backward is None else self.backward.trajectories.mapped

    def seen_from_b(self) -> SeenFromB | None:
        """These in-betweens with time running from keyframe B back to A (`SeenFromB`), or
        None for the one-sided transport, which has no paths of B's material."""
        return None if self.backward is None else SeenFromB(self)

    def __reduce__(self) -> tuple:
        """Pickled as the inputs of `from_map` (maps, fields, options), which rebuilds it
        in the other process (`parallel.Helper`): trajectories and transports are not sent."""
        if not hasattr(self, "_recipe"):
            raise TypeError("only an Inbetween made by Inbetween.from_map can be pickled")
        return self._recipe.__reduce__()

    # ------------------------------------------------------------------
    def levelset(self, s: float) -> np.ndarray:
        """The in-between signed distance field at time s in [0, 1], array of grid.shape.

        Negative inside; Phi at s = 0 and Psi at s = 1 exactly; equal to
        ``outside_value`` (> 0) wherever no transport reaches.
        """
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"time s must lie in [0, 1], got {s}.")
        if s == 0.0:
            return self.phi_a.copy()
        if s == 1.0:
            return self.phi_b.copy()
        key = round(s, 12)  # s and 1 - (1 - s) (`SeenFromB`) share a field
        if key in self._cache:
            return self._cache[key]
        t0 = time.perf_counter()
        if self.backward is None:
            field = (self._one_sided(s) if self.options.resample == "lookup"
                     else self._one_sided_idw(s))
            field = field.reshape(self.grid.shape)
            if self.keep_volume:
                field = self._keep_volume(field, s)
        else:
            field = self._banded(s)
        self.stats["levelset_seconds"] += time.perf_counter() - t0
        self.stats["levelset_calls"] += 1
        if len(self._cache) >= _CACHED_FIELDS:  # a frame asks for its field several times
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = field
        return field

    def _banded(self, s):
        """The two-sided in-between at s from the transports' narrow bands (`band`); made
        again from their whole regions where the band's floor comes near its surface."""
        field, deep = self._two_sided_frame(s)
        self.stats.setdefault("deep_nodes", {})[s] = int(np.count_nonzero(deep))
        if deep.any() and touches_surface(field, deep, self.grid):
            self.stats.setdefault("band_widened", []).append(s)
            field, _ = self._two_sided_frame(s, whole=True)
        return field

    def _two_sided_frame(self, s, whole=False):
        """The blend (`_two_sided`) with its creases filled and its volume kept, and the
        nodes that took a band's deep value (bool, grid.shape)."""
        field, meeting, deep = self._two_sided(s, whole)
        field = fill_creases(field.reshape(self.grid.shape), meeting, self.grid,
                             self.options.surface_tension,
                             min(1.0, min(s, 1.0 - s) / _TENSION_EASE))
        if self.keep_volume:
            field = self._keep_volume(field, s)
        return field, deep.reshape(self.grid.shape)

    def _two_sided(self, s, whole=False):
        """(1 - s) Phi_s + s Psi_s, each transport at its truncation where it does not reach;
        where a keyframe's parts meet (None: nowhere, or no surface tension); and where
        either transport took its band's deep value (``whole``: neither, both carried their
        whole regions)."""
        w = self.outside_value
        tension = self.options.surface_tension  # where parts meet, for `tension.fill_creases`
        reach = meeting_reach(self.grid, tension) if tension > 0 else None

        def carried(transport, t, other):
            return transport.carry_meeting(t, other, reach, whole)
        if self.threads > 1:
            with ThreadPoolExecutor(max_workers=1) as pool:  # independent: B's on a second core
                back = pool.submit(carried, self.backward, 1.0 - s, self.forward)
                phi_s, meet_a, deep_a = carried(self.forward, s, self.backward)
                psi_s, meet_b, deep_b = back.result()
        else:
            phi_s, meet_a, deep_a = carried(self.forward, s, self.backward)
            psi_s, meet_b, deep_b = carried(self.backward, 1.0 - s, self.forward)
        meetings = [m for m in (meet_a, meet_b) if m is not None]
        meeting = (np.logical_or.reduce(meetings).reshape(self.grid.shape) if meetings
                   else None)
        self.stats["covered_nodes"] = int(np.count_nonzero(~np.isnan(phi_s) | ~np.isnan(psi_s)))
        field, other = (np.nan_to_num(a, copy=False, nan=w) for a in (phi_s, psi_s))
        field *= 1.0 - s  # in place: both are grid-sized and this call's own
        other *= s
        field += other
        return field, meeting, deep_a | deep_b

    def hold_volumes(self, volumes: tuple[float, float]) -> None:
        """Hold (V_A, V_B), the keyframes' volumes as modelled (their meshes'), instead of
        their grids' (`isovolume`; each part's share scaled with them, `components`); the
        fields made before with others are made again."""
        volumes = (float(volumes[0]), float(volumes[1]))
        if volumes == self._end_volumes:
            return
        self._end_volumes = volumes
        self._components = None
        self._cache.clear()

    def _keep_volume(self, field, s):
        """Shift by the one iso-value that gives (1 - s) V_A + s V_B (`isovolume`); then,
        where the shifted in-between has several components, each by its own iso-value,
        for the volume of the material arriving in it (`components`,
        `isovolume.component_iso_values`)."""
        if self._end_volumes is None:
            self._end_volumes = (enclosed_volume(self.phi_a, self.grid),
                                 enclosed_volume(self.phi_b, self.grid))
        va, vb = self._end_volumes
        iso_value, err = volume_iso_value(field, self.grid, (1.0 - s) * va + s * vb)
        field -= iso_value  # the blend's own array
        labels, count = (component_labels(field) if self.options.volume_per_component
                         else (None, 1))
        if count > 1:
            if self._components is None:
                self._components = ComponentVolumes(self.grid, self.phi_a, self.phi_b,
                                                    self.forward.trajectories,
                                                    self.backward.trajectories,
                                                    volumes=self._end_volumes)
            own, errors = component_iso_values(field, self.grid, labels,
                                               self._components.targets(labels, count, s))
            iso_value += own[np.argmax(np.abs(own))]
            err = float(np.nanmax(np.abs(errors), initial=0.0))
        self.stats.setdefault("iso_value_h", {})[s] = iso_value / self.grid.spacing
        self.stats.setdefault("volume_error", {})[s] = err
        return field

    def _one_sided_values(self, s):
        """v_s = (1 - s) Phi(x) + s Psi(y(x)) at source points given in index coordinates."""
        fw = self.forward
        if fw.interpolation == "cubic" and self._coef_b is None:
            self._coef_b = ndimage.spline_filter(self.phi_b, order=3, mode="nearest")
        coef_b = self._coef_b

        def values(u):
            phi = fw.read(self.phi_a, u, fw._coef)
            y = self.trajectories(self.grid.to_world(u), 1.0)
            return (1.0 - s) * phi + s * fw.read(self.phi_b, self.grid.to_index(y), coef_b)
        return values

    def _one_sided(self, s):
        out = self.forward.carry(s, values=self._one_sided_values(s))
        self.stats["covered_nodes"] = int(np.count_nonzero(~np.isnan(out)))
        return np.nan_to_num(out, nan=self.outside_value)

    def _one_sided_idw(self, s):
        tr = self.trajectories
        nodes = np.flatnonzero(tr.region_nodes())
        u = self.grid.to_index(self.grid.points().reshape(-1, self.grid.dim)[nodes])
        vals = np.minimum(self._one_sided_values(s)(u), self.outside_value)
        field, covered = idw_resample(self.grid, tr.node_positions(s, nodes), vals,
                                      fill=self.outside_value, radius=self.options.idw_radius)
        self.stats["covered_nodes"] = int(covered.sum())
        return field

    def trajectory(self, points: ArrayLike, s: float) -> np.ndarray:
        """Positions at time s of points of keyframe A given at time 0: (P, d) -> (P, d).

        Multilinear interpolation of A's node trajectories.
        """
        return self.trajectories(points, s)

    def velocity(self, points: ArrayLike, s: float, ds: float = 1e-3, near_cells: float = 2.5,
                 neighbours: int = 12) -> np.ndarray:
        """Velocity dx/ds (world units per unit s) at world points on the level set at time s.

        The surface at time s is made of the material each transport carries:
        the nodes near each keyframe's own surface, moved along their paths,
        with velocities from second-order finite differences of the paths
        (eq. 3.1 differentiated in s; B's nodes run backward, so their velocity is
        -dx_B/dt at t = 1 - s). Each point gets the value at it of a weighted
        least-squares affine fit of the velocities of its ``neighbours``
        nearest moved nodes (moving least squares, exact for any rigid or
        affine motion); A's nodes weigh (1 - s), B's s, as in the blend, so
        the velocity hands over from A's motion to B's without a jump.

        Parameters
        ----------
        points : (P, d) array, world units (e.g. the vertices of ``levelset(s)``'s surface).
        s : float in [0, 1]
        ds : float
            Step of the finite difference; one frame (1 / frames of the segment) reuses
            the paths of the neighbouring frames.
        near_cells : float
            Nodes within this many cells of their keyframe's surface take part.
        neighbours : int
            Moved nodes in each point's fit.

        Returns
        -------
        (P, d) array, world units per unit s (divide by the frames of the segment for
        units per frame).
        """
        s = float(s)
        if not 0.0 <= s <= 1.0:
            raise ValueError(f"time s must lie in [0, 1], got {s}.")
        p = np.asarray(points, dtype=float)
        d = self.grid.dim
        if p.ndim != 2 or p.shape[1] != d:
            raise ValueError(f"points must have shape (P, {d}), got {p.shape}.")
        h = self.grid.spacing
        parts = [self.forward.surface_motion(s, near_cells * h, ds) + (1.0 - s,)]
        if self.backward is not None:
            pos, vel = self.backward.surface_motion(1.0 - s, near_cells * h, ds)
            parts.append((pos, -vel, s))
        parts = [(pos, vel, np.full(len(pos), wt)) for pos, vel, wt in parts if wt > 0]
        pos, vel, weight = (np.concatenate(a) for a in zip(*parts))
        if p.shape[0] == 0 or pos.shape[0] == 0:
            return np.zeros_like(p)
        k = min(int(neighbours), pos.shape[0])
        # built once per frame and queried once: the unbalanced, uncompacted tree builds in
        # under half the time and answers the same neighbours
        tree = cKDTree(pos, balanced_tree=False, compact_nodes=False)
        dist, idx = tree.query(p, k=k, workers=-1)
        dist, idx = dist.reshape(len(p), k), idx.reshape(len(p), k)
        w = weight[idx] / (dist ** 2 + (0.5 * h) ** 2)
        return _affine_fit_at(p, pos[idx], vel[idx], w, h)


class SeenFromB:
    """An `Inbetween` seen from keyframe B: at time t the level set of s = 1 - t, and the
    paths of B's material (the backward transport's, eq. 3.1 run from B). A template
    tracked from B's own mesh reads these (`template.DetailTrack`), as one from A's reads
    the `Inbetween` itself."""

    def __init__(self, inbetween: Inbetween) -> None:
        self.inbetween, self.grid = inbetween, inbetween.grid

    def levelset(self, t: float) -> np.ndarray:
        """The in-between level set at s = 1 - t."""
        return self.inbetween.levelset(1.0 - float(t))

    def trajectory(self, points: ArrayLike, t: float) -> np.ndarray:
        """Positions at time t of points of keyframe B given at t = 0: (P, d) -> (P, d)."""
        return self.inbetween.backward.trajectories(points, t)


class _Paths:
    """How `Inbetween.from_map` makes a keyframe's trajectories: on ``grid``, or solved on
    the ``motion_grid`` and read at ``grid``'s nodes (`finepaths.FinePaths`)."""

    def __init__(self, grid, motion_grid, options, cancel):
        self.grid, self.motion_grid = grid, motion_grid
        self.keywords = dict(options.trajectory_keywords(), cancel=cancel)

    def on_motion(self, field):
        """A surface-grid field on the grid the maps live on."""
        if self.motion_grid is None:
            return field
        return on_motion_grid(field, self.grid, self.motion_grid)

    def __call__(self, field, mapped, material, components=None, bend=None, parts=None):
        """The paths of the keyframe whose surface-grid field is ``field``, along ``mapped``
        (``material``, ``components``, the ``bend`` and the ``parts`` on the maps' grid)."""
        solved = self.solved(field, mapped, material, components, parts)
        solved.bend = bend
        if self.motion_grid is None:
            return solved
        return FinePaths(self.grid, solved, field < 0, self.keywords["margin_cells"])

    def solved(self, field, mapped, material, components=None, parts=None):
        """The as-rigid-as-possible paths on the maps' grid (`trajectory.Trajectories`)."""
        if self.motion_grid is None:
            return Trajectories(self.grid, mapped, material, components, parts=parts,
                                **self.keywords)
        mass = material_mass(field < 0, self.grid, self.motion_grid)
        kw = dict(self.keywords, margin_cells=same_width(self.keywords["margin_cells"],
                                                         self.grid, self.motion_grid))
        return Trajectories(self.motion_grid, mapped, material, components, mass=mass,
                            parts=parts, **kw)

    def cells(self, crack):
        """A bool over the maps' grid's cells (None: None) on the surface grid's cells:
        a surface cell is in it when its centre lies in one of its cells."""
        if crack is None or self.motion_grid is None:
            return crack
        lower = np.stack(np.meshgrid(*(np.arange(n - 1) for n in self.grid.shape),
                                     indexing="ij"), axis=-1)
        at = self.motion_grid.to_index(self.grid.to_world(lower + 0.5))
        cell = np.clip(np.floor(at).astype(np.int64), 0, np.asarray(crack.shape) - 1)
        return crack[tuple(np.moveaxis(cell, -1, 0))]

    def back_map(self, forward):
        """The map B -> A as the inverse of ``forward``'s, on the maps' grid."""
        inverse = invert_map(self.grid, forward)
        if self.motion_grid is None:
            return inverse
        points = self.motion_grid.points()
        return points + sample(inverse - self.grid.points(), self.grid, points)


def _transports(phi_a, phi_b, paths, mapped, mapped_back, material, components, options, cancel,
                bends, cracks=(None, None), parts=(None, None)):
    """The forward transport of A's field along the map A -> B, and (two-sided) the backward
    one of B's field along B -> A (`invert_map` of the forward one when not given), both
    truncated at one value so that the far field is one value; their paths bent by
    ``bends`` (forward, backward), the cells of each map's crack left out (``cracks``), the
    paths of each map's ``parts`` apart."""
    lookup = dict(options.lookup_keywords(), cancel=cancel)

    def carried(field, y, mat, comps=None, bend=None, crack=None, part=None):
        return Transport(field, paths(field, np.asarray(y, dtype=float), mat, comps, bend, part),
                         torn=paths.cells(crack), **lookup)

    backward = None
    if options.two_sided and mapped_back is not None:
        with ThreadPoolExecutor(max_workers=1) as pool:  # two trajectory solves, two cores
            back = pool.submit(carried, phi_b, mapped_back, paths.on_motion(phi_b) < 0,
                               None, bends[1], cracks[1], parts[1])
            forward = carried(phi_a, mapped, material, components, bends[0], cracks[0],
                              parts[0])
            backward = back.result()
    else:
        forward = carried(phi_a, mapped, material, components, bends[0], cracks[0], parts[0])
        if options.two_sided:
            backward = carried(phi_b, paths.back_map(forward), paths.on_motion(phi_b) < 0,
                               None, bends[1])
    if backward is not None:
        w = min(forward.border_value, backward.border_value)
        forward.truncation = backward.truncation = w
    return forward, backward


def back_map(phi_a: np.ndarray, phi_b: np.ndarray, grid: Grid, mapped: ArrayLike, *,
             material: np.ndarray | None = None, components: np.ndarray | None = None,
             parts: np.ndarray | None = None,
             motion_grid: Grid | None = None, options: MotionOptions | None = None,
             cancel: Callable[[], bool] | None = None) -> np.ndarray:
    """The map B -> A of a segment given only its map A -> B: `invert_map` of the forward
    paths, on the maps' grid (as `Inbetween.from_map` makes it when not given; ``parts``
    those of the map A -> B)."""
    options = options or MotionOptions()
    paths = _Paths(grid, motion_grid, options, cancel)
    if material is None:
        material = paths.on_motion(phi_a) < 0
    forward, _ = _transports(phi_a, phi_b, paths, np.asarray(mapped, dtype=float), None,
                             material, components,
                             dataclasses.replace(options, transport="one-sided"), cancel,
                             (None, None), parts=(parts, None))
    return paths.back_map(forward)


def path_start_velocity(field: np.ndarray, grid: Grid, mapped: ArrayLike, *,
                        material: np.ndarray | None = None, components: np.ndarray | None = None,
                        parts: np.ndarray | None = None, motion_grid: Grid | None = None,
                        options: MotionOptions | None = None,
                        cancel: Callable[[], bool] | None = None) -> np.ndarray:
    """The velocity (per unit s) as they leave their keyframe of the paths a segment's
    transport of ``field`` follows along ``mapped`` (``material``, ``components``, ``parts``
    on the maps' grid: A's, or None for B's), built as `Inbetween.from_map` builds them,
    on the maps' grid: (size, d), for `spline.chain_bends`."""
    paths = _Paths(grid, motion_grid, options or MotionOptions(), cancel)
    if material is None:
        material = paths.on_motion(field) < 0
    return start_velocity(paths.solved(field, np.asarray(mapped, dtype=float), material,
                                       components, parts))


def _from_recipe(args, kwargs):
    return Inbetween.from_map(*args, **kwargs)


class Recipe:
    """The inputs of `Inbetween.from_map` (maps, fields, options): pickled, it becomes the
    in-betweens where it is unpickled (`parallel.Helper`), built there."""

    def __init__(self, args: tuple, kwargs: dict[str, Any]) -> None:
        self.args, self.kwargs = args, kwargs

    def __reduce__(self) -> tuple[Callable[..., Inbetween], tuple[tuple, dict[str, Any]]]:
        return _from_recipe, (self.args, self.kwargs)


def map_agreement(grid: Grid, forward: Trajectories | FinePaths, backward: Trajectories | FinePaths,
                  material: np.ndarray) -> tuple[float, float]:
    """|y_BA(y_AB(x)) - x| in grid spacings over A's material nodes: (mean, max), from the
    two maps' paths at s = 1 (`Trajectories` or `finepaths.FinePaths`)."""
    nodes = np.flatnonzero(material)
    if nodes.size == 0:
        return (float("nan"), float("nan"))
    x = grid.node_points(nodes)
    back = backward(forward.node_positions(1.0, nodes), 1.0)
    err = np.linalg.norm(back - x, axis=-1) / grid.spacing
    return (float(err.mean()), float(err.max()))


def _affine_fit_at(p, pos, val, w, h, ridge=1e-6):
    """Value at each point p (P, d) of the weighted least-squares affine fit of the values
    ``val`` (P, k, m) given at its k neighbours ``pos`` (P, k, d) with weights ``w`` (P, k),
    with a ``ridge`` on the slope (in units of h).

    Centred on the weighted mean of the neighbours, the fit's constant is the weighted mean
    value and its slope solves a d x d system per point (closed-form inverse): the same
    fit as the (d + 1) x (d + 1) normal equations, without a batched LAPACK call per point.
    """
    wsum = w.sum(axis=1)
    xb = np.einsum("pk,pkd->pd", w, pos) / wsum[:, None]
    vb = np.einsum("pk,pkm->pm", w, val) / wsum[:, None]
    D = (pos - xb[:, None]) / h
    C = np.einsum("pk,pki,pkj->pij", w, D, D) + ridge * np.eye(p.shape[1])
    B = np.einsum("pk,pki,pkm->pim", w, D, val - vb[:, None])
    G = np.matmul(inverse(C), B)
    return vb + np.einsum("pi,pim->pm", (p - xb) / h, G)
