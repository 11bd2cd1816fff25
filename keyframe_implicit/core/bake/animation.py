"""The result of a bake: one tracked mesh per timeline frame, and each frame's own surface."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from ..base.grid import Grid
    from ..surface.attributes import MeshAttributes
    from ..surface.meshdata import MeshData

__all__ = ["Animation", "KeyframeTrack"]


@dataclass
class KeyframeTrack:
    """A keyframe's own mesh tracked into a segment next to it (`template.DetailTrack`),
    for the mesh sequence where no earlier mesh follows: forward through the segment the
    keyframe begins (after a topology change, a segment that keeps its topology shows
    the artist's mesh again), or back along B's paths through the one it ends (the
    frames before the keyframe then lead into its mesh, not a frame's own surface).

    key_row : the row of the keyframe's frame in `Animation.frames`.
    first_row : the row of ``vertices[0]``: ``key_row`` forward, the segment's first
        in-between back.
    faces : (F, 3) the keyframe's triangles.
    vertices : (m, V, 3) float32, the tracked mesh on rows ``first_row`` on, in timeline
        order; on ``key_row`` the keyframe's mesh itself.
    figures : per row as ``vertices``, what `chain.tracked_frames` judges the tracked mesh
        by (``steered``, ``shape_keys``, ``volumes``, ``flipped``).
    ships : on how many frames from the keyframe on (forward) or back the mesh sequence
        ships it (`pipeline` decides; the segment's other keyframe shows its own mesh).
    """

    key_row: int
    first_row: int
    faces: np.ndarray
    vertices: np.ndarray
    figures: list[dict[str, Any]]
    ships: int = 0

    @property
    def step(self) -> int:
        """+1 forward from the keyframe, -1 back."""
        return 1 if self.first_row == self.key_row else -1

    def outward(self) -> list[int]:
        """Indices into ``vertices`` from the keyframe's own row outward."""
        key = self.key_row - self.first_row
        return list(range(key, len(self.vertices))) if self.step > 0 else list(range(key, -1, -1))

    def at(self, i: int) -> int | None:
        """The index into ``vertices`` of row i where it ships, else None."""
        if 0 < (i - self.key_row) * self.step <= self.ships:
            return i - self.first_row
        return None


@dataclass
class Animation:
    """Result of `animate` and `chain.animate_chain`: the tracked template on every frame,
    and each frame's own surface.

    frames : (n,) int array, every timeline frame from the first keyframe's to the last's.
    vertices : (n, V, d) float array, the template's vertex positions on each frame
        (float32 from `animate`).
    faces : (F, 3) int triangles (3D) or (E, 2) segments (2D), the template's, the same
        on every frame.
    grid : the `Grid` used.
    stats : dict of figures (timings, solver iterations, volumes, uncovered area, ...), and
        ``quality``: per output ("shape_keys", "mesh_sequence") one dict of
        `quality.frame_quality` figures per frame (keyframe frames also carry
        `quality.keyframe_distance` to the keyframe mesh given), ``output`` /
        ``output_reason``: the output `quality.choose_output` picks.
    surfaces : list, per frame, of (V_f, 3) float32 vertices and (F_f, 3) int32 triangles:
        the frame's own surface (topology free), world units.
    velocities : list, per frame, of (V_f, 3) float32: velocity of every vertex of
        ``surfaces`` in world units per frame (the trajectories' rate, eq. 3.1).
    levelsets : list, per frame, of float32 arrays of grid.shape: the in-between level sets
        (eq. 3.4), kept when `animate` is called with ``levelsets=True``.
    attributes : `attributes.MeshAttributes` of ``vertices`` / ``faces`` (polygons, UVs,
        materials, ...) when the template is the first keyframe's own mesh, else None
        (``faces`` are then its polygons' fan triangles).
    keyframe_attributes : dict timeline frame -> `attributes.MeshAttributes` of the keyframe
        mesh that frame's surface is (with the artist's mesh, a keyframe's frame in
        ``surfaces`` is the keyframe's own mesh).
    prepared : dict output kind -> `meshdata.MeshData`, the output meshes made so far
        (`output_mesh`; the worker process makes the one the bake will store).
    tracked : (n,) bool array, optional: the frames the mesh sequence ships as the tracked
        template rather than as their own surface (`chain.tracked_frames`: those before a
        topology change); None or empty, none.
    keyframe_tracks : the `KeyframeTrack`s made (the mesh sequence with the artist's
        meshes); each ships where its ``ships`` says.
    """

    frames: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray
    grid: Grid
    stats: dict[str, Any] = field(default_factory=dict)
    surfaces: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    velocities: list[np.ndarray] = field(default_factory=list)
    levelsets: list[np.ndarray] = field(default_factory=list)
    attributes: MeshAttributes | None = None
    keyframe_attributes: dict[int, MeshAttributes] = field(default_factory=dict)
    prepared: dict[str, MeshData] = field(default_factory=dict)
    tracked: np.ndarray | None = None
    keyframe_tracks: list[KeyframeTrack] = field(default_factory=list)

    def is_tracked(self, i: int) -> bool:
        """Whether the mesh sequence ships frame i as the tracked template (``tracked``)."""
        return self.tracked is not None and i < len(self.tracked) and bool(self.tracked[i])

    def _artist_track(self, i: int) -> tuple[np.ndarray, int, int, np.ndarray,
                                              MeshAttributes | None] | None:
        """(vertices per row in timeline order, frame i's index there, the index of the
        keyframe the mesh is, its triangles and attributes) where the mesh sequence ships
        an artist's mesh tracked on frame i: the template (`is_tracked`) or a
        `KeyframeTrack`; else None."""
        if self.is_tracked(i):
            return self.vertices, i, 0, self.faces, self.attributes
        for track in self.keyframe_tracks:
            j = track.at(i)
            if j is not None:
                attrs = self.keyframe_attributes.get(int(self.frames[track.key_row]))
                return (track.vertices, j, track.key_row - track.first_row, track.faces,
                        attrs)
        return None

    def sequence_frame(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(vertices, triangles) the mesh sequence ships on frame i: an artist's mesh
        tracked (the template where ``tracked`` says so, a `KeyframeTrack` where it ships),
        else the frame's own surface."""
        track = self._artist_track(i)
        if track is None:
            return self.surfaces[i]
        vertices, j, _, faces, _ = track
        return vertices[j], faces

    def sequence_attributes(self, i: int) -> MeshAttributes | None:
        """`attributes.MeshAttributes` of `sequence_frame` (i), or None: on a tracked frame
        the artist's own (``attributes``, or a `KeyframeTrack`'s keyframe's), as on the
        shape keys, its custom normals turned with their polygons (`_turned_normals`);
        else its surface's (`surface_attributes`)."""
        track = self._artist_track(i)
        if track is None:
            return self.surface_attributes(i)
        vertices, j, key, _, attrs = track
        if attrs is None or attrs.custom_normals is None or j == key:
            return attrs
        return replace(attrs, custom_normals=_turned_normals(attrs, vertices[key],
                                                             vertices[j]))

    def sequence_velocity(self, i: int) -> np.ndarray:
        """Velocity of `sequence_frame` (i)'s vertices, world units per frame: a tracked
        frame's from its neighbours' on the same mesh (one-sided at the ends), else
        ``velocities``."""
        track = self._artist_track(i)
        if track is None:
            return self.velocities[i]
        vertices, j = track[:2]
        lo, hi = max(j - 1, 0), min(j + 1, len(vertices) - 1)
        step = np.asarray(vertices[hi], float) - np.asarray(vertices[lo], float)
        return (step / max(hi - lo, 1)).astype(np.float32)

    def output_mesh(self, kind: str) -> MeshData:
        """`meshdata.MeshData` of the output ``kind`` ("shape_keys" or "mesh_sequence"),
        made once (`meshdata.output_mesh`) and kept in ``prepared``."""
        if kind not in self.prepared:
            from ..surface.meshdata import output_mesh

            self.prepared[kind] = output_mesh(self, kind)
        return self.prepared[kind]

    def surface_attributes(self, i: int) -> MeshAttributes | None:

        """`attributes.MeshAttributes` of frame i's own surface (``surfaces[i]``), or None.

        Each surface vertex's source is its closest point on the tracked template of the
        same frame, whose barycentric position on its triangle is a point of keyframe A's
        mesh: UVs and colours are read there (`attributes.transfer`, seams kept out of
        triangles), the material from the source face. Computed on demand: a bake stored as
        shape keys never needs it.
        """
        if self.attributes is None or not self.surfaces:
            return None
        own = self.keyframe_attributes.get(int(self.frames[i]))
        if own is not None:  # a keyframe's frame shows the keyframe's own mesh
            return own
        from ..surface.attributes import transfer

        return transfer(self.attributes, self.vertices[i], *self.surfaces[i])


def _turned_normals(attributes: MeshAttributes, start: np.ndarray, now: np.ndarray) -> np.ndarray:
    """``attributes.custom_normals`` (world space, per loop) turned as each polygon turned
    from the vertices ``start`` to ``now``: the rotation taking the frame of the polygon's
    first corner (its first edge and its normal) at ``start`` to that at ``now``. Blender
    keeps custom normals relative to their faces, so shape keys turn them the same way."""
    first = np.asarray(attributes.loop_start, dtype=np.int64)
    corners = np.asarray(attributes.loop_vertices, dtype=np.int64)
    tri = np.stack([corners[first], corners[first + 1], corners[first + 2]], axis=1)

    def frames(v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
        e = b - a
        n = np.cross(e, c - a)
        e /= np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
        return np.stack([e, np.cross(n, e), n], axis=2)  # columns: the polygon's axes
    turn = frames(now) @ np.swapaxes(frames(start), 1, 2)
    poly = np.repeat(np.arange(len(first)), np.asarray(attributes.loop_total, dtype=np.int64))
    normals = np.asarray(attributes.custom_normals, dtype=float)
    return np.einsum("lij,lj->li", turn[poly], normals).astype(np.float32)
