"""The artist's mesh beyond its triangles, as plain arrays, and its transfer by closest points.

A keyframe is a finished asset: polygons (quads and n-gons), UV maps, colour
attributes, per-face materials and smooth flags, sharp and seam edges,
custom split normals. `MeshAttributes` holds them as numpy arrays in
Blender's own layout (polygons as loop start / loop total / loop vertex
indices, UVs and corner colours per loop), so the core stays free of bpy
and the Blender side copies them with ``foreach_get`` / ``foreach_set``.

The thesis carries texture coordinates and colours through the map (its
sec. 3.2). Two uses here:

- shape keys: keyframe A's own mesh is the template (`template`), so its
  attributes ride along unchanged;
- a per-frame surface (mesh sequence): `transfer` gives every corner of a
  new triangle mesh the attributes of its source point's closest point on
  the keyframe mesh (barycentric within the source triangle), all three
  corners of a triangle read from one side of a UV seam; `concatenate`
  joins the frames' attributes into those of one mesh holding every frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Iterable, Sequence

    from numpy.typing import ArrayLike

__all__ = ["MeshAttributes", "closest_points", "barycentric", "transfer", "concatenate"]


@dataclass
class MeshAttributes:
    """Polygons and attributes of a keyframe mesh (Blender's layout, plain arrays).

    loop_start, loop_total : (P,) int, each polygon's first loop and its corner count.
    loop_vertices : (L,) int, the vertex of each loop (corner).
    uv_maps : dict name -> (L, 2) float32, per loop; the first is the active one.
    colors : dict name -> (domain, data_type, (N, 4) float32): domain "POINT" (N = V) or
        "CORNER" (N = L), data_type Blender's ("FLOAT_COLOR" or "BYTE_COLOR").
    material_index : (P,) int, optional; index into ``material_names``.
    material_names : list of str, the object's material slots in order ("" for empty slots).
    smooth : (P,) bool, optional; smooth-shaded polygons.
    edges : (E, 2) int, optional; with ``sharp_edges`` and ``seams`` ((E,) bool) on them.
    custom_normals : (L, 3) float32, optional; custom split normals per loop (world space).
    """

    loop_start: np.ndarray
    loop_total: np.ndarray
    loop_vertices: np.ndarray
    uv_maps: dict[str, np.ndarray] = field(default_factory=dict)
    colors: dict[str, tuple[str, str, np.ndarray]] = field(default_factory=dict)
    material_index: np.ndarray | None = None
    material_names: list[str] = field(default_factory=list)
    smooth: np.ndarray | None = None
    edges: np.ndarray | None = None
    sharp_edges: np.ndarray | None = None
    seams: np.ndarray | None = None
    custom_normals: np.ndarray | None = None

    @classmethod
    def from_triangles(cls, faces: ArrayLike) -> MeshAttributes:
        """Attributes of a plain triangle mesh: polygons only."""
        f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
        return cls(np.arange(0, f.size, 3), np.full(len(f), 3), f.reshape(-1))

    @property
    def n_polygons(self) -> int:
        """How many polygons the mesh has."""
        return len(self.loop_start)

    @property
    def n_loops(self) -> int:
        """How many polygon corners (loops) the mesh has."""
        return len(self.loop_vertices)

    def check(self, n_vertices: int) -> None:
        """ValueError naming the first inconsistency with a mesh of ``n_vertices`` vertices."""
        start = np.asarray(self.loop_start)
        total = np.asarray(self.loop_total)
        loops = np.asarray(self.loop_vertices)
        if start.shape != total.shape or start.ndim != 1:
            raise ValueError("loop_start and loop_total must be (P,) arrays of the same length.")
        if np.any(total < 3):
            raise ValueError("every polygon needs at least 3 corners.")
        if len(start) and (start.min() < 0 or (start + total).max() > len(loops)):
            raise ValueError("polygons reach past the loops: loop_start + loop_total > loops.")
        if len(loops) and (loops.min() < 0 or loops.max() >= n_vertices):
            raise ValueError(f"loop vertices must lie in [0, {n_vertices - 1}].")
        for name, uv in self.uv_maps.items():
            if np.shape(uv) != (len(loops), 2):
                raise ValueError(f"UV map '{name}' must have one (u, v) per loop "
                                 f"({len(loops)}), got shape {np.shape(uv)}.")
        for name, (domain, _, data) in self.colors.items():
            n = n_vertices if domain == "POINT" else len(loops)
            if np.shape(data) != (n, 4):
                raise ValueError(f"colour attribute '{name}' must be ({n}, 4) on its {domain} "
                                 f"domain, got shape {np.shape(data)}.")
        for name in ("material_index", "smooth"):
            a = getattr(self, name)
            if a is not None and np.shape(a) != (len(start),):
                raise ValueError(f"{name} must have one value per polygon ({len(start)}).")
        if self.custom_normals is not None and np.shape(self.custom_normals) != (len(loops), 3):
            raise ValueError(f"custom_normals must be ({len(loops)}, 3), one per loop.")

    def triangle_loops(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, 3) loop indices of the polygons' fan triangles, and (T,) their polygon.

        Fans around each polygon's first corner, as `mesh.triangulate` makes them,
        so ``loop_vertices[triangle_loops()[0]]`` are the mesh's triangles.
        """
        start = np.asarray(self.loop_start, dtype=np.int64)
        total = np.asarray(self.loop_total, dtype=np.int64)
        n_tri = total - 2
        poly = np.repeat(np.arange(len(start)), n_tri)
        first = np.repeat(start, n_tri)
        k = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
        return np.stack([first, first + k + 1, first + k + 2], axis=1), poly

    def triangles(self) -> np.ndarray:
        """(T, 3) vertex triangles of the polygons (fans)."""
        return np.asarray(self.loop_vertices, dtype=np.int64)[self.triangle_loops()[0]]


def closest_points(points: ArrayLike, vertices: ArrayLike, triangles: ArrayLike,
                   candidates: int = 16) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points on a triangle mesh: (P, 3) points, (P,) triangle, (P, 3) barycentrics.

    Exact point-triangle closest points (`triangles.Triangles`) over the ``candidates``
    triangles whose centroids lie nearest (`triangles.nearest_candidates`), the nearest
    of them kept; `quality.mesh_distance` measures distances the same way.
    """
    from ..fields.triangles import Triangles, nearest_candidates, proper

    p = np.asarray(points, dtype=float).reshape(-1, 3)
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    t = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
    keep = proper(v, t)
    if len(keep) == 0:
        raise ValueError("the mesh has no triangle of non-zero area.")
    idx = nearest_candidates(p, v, t[keep], candidates)
    k = idx.shape[1]
    cand = keep[idx].reshape(-1)
    kernel = Triangles(v, t[keep])
    local = np.searchsorted(keep, cand)
    q = kernel.closest_point(np.repeat(p, k, axis=0), local).reshape(len(p), k, 3)
    best = np.argmin(np.einsum("pkd,pkd->pk", q - p[:, None], q - p[:, None]), axis=1)
    rows = np.arange(len(p))
    q = q[rows, best]
    tri = cand.reshape(len(p), k)[rows, best]
    return q, tri, barycentric(q, *(v[t[tri, i]] for i in range(3)))


def barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Barycentric coordinates (P, 3) of points p in triangles (a, b, c), clipped to the triangle."""
    bary = np.clip(_plane_barycentric(p, a, b, c), 0.0, 1.0)
    return bary / np.maximum(bary.sum(axis=1, keepdims=True), 1e-300)


def transfer(attributes: MeshAttributes, vertices: ArrayLike, sources: ArrayLike,
             faces: ArrayLike) -> MeshAttributes:
    """Attributes of a new triangle mesh read from a keyframe mesh at source points.

    Parameters
    ----------
    attributes : MeshAttributes of the keyframe mesh (polygons, UVs, colours, materials).
    vertices : (V, 3) the keyframe mesh's vertices (or the same mesh tracked to a frame:
        barycentric positions carry over).
    sources : (N, 3) the source point of every vertex of the new mesh (on or near the mesh).
    faces : (F, 3) int, the new mesh's triangles.

    Returns
    -------
    MeshAttributes of the new mesh (one polygon per triangle): every corner takes the
    barycentric UVs / colours at its source's closest point on the keyframe mesh. A
    triangle whose corners land in different UV islands (across a seam) reads all three
    corners from the source triangle under its centroid (`_spans_seam`), so its UVs never span a
    seam. Material and smooth flag come from the source polygon of the centroid.
    """
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    src = np.asarray(sources, dtype=float).reshape(-1, 3)
    out = _uniform(attributes, f)
    if out is not None:
        return out
    tri_loops, tri_poly = attributes.triangle_loops()
    lv = np.asarray(attributes.loop_vertices, dtype=np.int64)
    tris = lv[tri_loops]
    v = np.asarray(vertices, dtype=float)
    corner_src = src[f.reshape(-1)]
    _, t_vertex, b_vertex = closest_points(src, v, tris)  # once per vertex, not per corner
    _, t_centre, _ = closest_points(src[f].mean(axis=1), v, tris)
    t_corner, b_corner = t_vertex[f], b_vertex[f]
    poly_centre = tri_poly[t_centre]
    if attributes.uv_maps:
        uv = np.concatenate([np.asarray(m, dtype=float) for m in attributes.uv_maps.values()], 1)
        across = _spans_seam(uv, tri_loops, t_corner, b_corner, v, tris, corner_src.reshape(-1, 3, 3))
        # those read all corners from the source triangle under their centroid, extended
        # past its edges in its plane (UVs are smooth within it)
        a, b, c = (v[tris[np.repeat(t_centre[across], 3), i]] for i in range(3))
        ext = _plane_barycentric(corner_src.reshape(-1, 3, 3)[across].reshape(-1, 3), a, b, c)
        t_corner[across] = t_centre[across, None]
        b_corner[across] = ext.reshape(-1, 3, 3)
    def corners(loop_values: np.ndarray) -> np.ndarray:
        """Per new corner (3F, k): the barycentric value at its source point."""
        own = np.einsum("fci,fcik->fck", b_corner, loop_values[tri_loops[t_corner]])
        return own.reshape(-1, own.shape[-1])

    out = MeshAttributes.from_triangles(f)
    for name, uv in attributes.uv_maps.items():
        out.uv_maps[name] = corners(np.asarray(uv, dtype=float)).astype(np.float32)
    for name, (domain, dtype, data) in attributes.colors.items():
        data = np.asarray(data, dtype=float)
        loop_data = data[lv] if domain == "POINT" else data
        out.colors[name] = ("CORNER", dtype, np.clip(corners(loop_data), 0.0, None)
                            .astype(np.float32))
    if attributes.material_index is not None:
        out.material_index = np.asarray(attributes.material_index)[poly_centre]
    out.material_names = list(attributes.material_names)
    if attributes.smooth is not None:
        out.smooth = np.asarray(attributes.smooth)[poly_centre]
    return out


def _uniform(attributes: MeshAttributes, faces: np.ndarray) -> MeshAttributes | None:
    """The attributes of new triangles ``faces`` when the keyframe mesh has nothing that
    varies over its surface (no UVs or colours, one material, one shading): then no source
    point needs to be found. None otherwise."""
    if attributes.uv_maps or attributes.colors:
        return None
    per_face = {}
    for name in ("material_index", "smooth"):
        values = getattr(attributes, name)
        if values is not None and len(values):
            if np.any(np.asarray(values) != np.asarray(values)[0]):
                return None
            per_face[name] = np.full(len(faces), np.asarray(values)[0])
    out = MeshAttributes.from_triangles(faces)
    out.material_names = list(attributes.material_names)
    for name, values in per_face.items():
        setattr(out, name, values)
    return out


def concatenate(parts: Iterable[MeshAttributes], n_vertices: Sequence[int]) -> MeshAttributes:
    """The attributes of one mesh made of several laid end to end.

    Parameters
    ----------
    parts : sequence of MeshAttributes, one per mesh, in order.
    n_vertices : sequence of int, each mesh's vertex count: part k's loop vertices and
        edges are offset by the vertices of the parts before it.

    Returns
    -------
    MeshAttributes whose polygons, loops, UV maps, colours, material indices, smooth
    flags, edge flags and custom normals are the parts' in order. An attribute that only
    some parts have is filled with its neutral value on the others: UV (0, 0), colour 0,
    material 0, smooth, no sharp edge or seam, custom normal (0, 0, 0) (Blender's own).
    ``material_names`` are every part's, each name once, in order of first use; each
    part's material indices are renumbered into them.
    """
    parts = list(parts)
    if len(parts) != len(n_vertices):
        raise ValueError(f"{len(parts)} attribute sets for {len(n_vertices)} vertex counts.")
    loops = [p.n_loops for p in parts]
    polygons = [p.n_polygons for p in parts]
    v_off = np.concatenate([[0], np.cumsum(n_vertices, dtype=np.int64)[:-1]])
    l_off = np.concatenate([[0], np.cumsum(loops, dtype=np.int64)[:-1]])

    def joined(values: list[np.ndarray | None], rows: Sequence[int], fill: float | bool,
               dtype: type) -> np.ndarray | None:
        """``values`` (one array or None per part) in one array; None -> ``fill`` rows."""
        if all(v is None for v in values):
            return None
        width = next(np.shape(v)[1:] for v in values if v is not None)
        return np.concatenate([np.full((n,) + width, fill, dtype) if v is None
                               else np.asarray(v, dtype) for v, n in zip(values, rows)])

    out = MeshAttributes(
        np.concatenate([np.asarray(p.loop_start, np.int64) + o for p, o in zip(parts, l_off)]),
        np.concatenate([np.asarray(p.loop_total, np.int64) for p in parts]),
        np.concatenate([np.asarray(p.loop_vertices, np.int64) + o
                        for p, o in zip(parts, v_off)]),
        material_names=list(parts[0].material_names))
    for name in dict.fromkeys(n for p in parts for n in p.uv_maps):
        out.uv_maps[name] = joined([p.uv_maps.get(name) for p in parts], loops, 0.0, np.float32)
    for name in dict.fromkeys(n for p in parts for n in p.colors):
        kinds = {p.colors[name][:2] for p in parts if name in p.colors}
        if len(kinds) > 1:
            raise ValueError(f"colour attribute '{name}' has different domains or types: "
                             f"{sorted(kinds)}.")
        domain, data_type = kinds.pop()
        data = [p.colors[name][2] if name in p.colors else None for p in parts]
        rows = n_vertices if domain == "POINT" else loops
        out.colors[name] = (domain, data_type, joined(data, rows, 0.0, np.float32))
    out.material_names = list(dict.fromkeys(n for p in parts for n in p.material_names))
    out.material_index = joined([_slots_in(p, out.material_names) for p in parts], polygons, 0,
                                np.int64)
    out.smooth = joined([p.smooth for p in parts], polygons, True, bool)
    out.custom_normals = joined([p.custom_normals for p in parts], loops, 0.0, np.float32)
    edged = [(p, o) for p, o in zip(parts, v_off) if p.edges is not None]
    if edged:
        out.edges = np.concatenate([np.reshape(p.edges, (-1, 2)).astype(np.int64) + o
                                    for p, o in edged])
        counts = [len(p.edges) for p, _ in edged]
        out.sharp_edges = joined([p.sharp_edges for p, _ in edged], counts, False, bool)
        out.seams = joined([p.seams for p, _ in edged], counts, False, bool)
    return out


def _slots_in(part: MeshAttributes, names: list[str]) -> np.ndarray | None:
    """``part.material_index`` renumbered into the slot list ``names`` (a part without slot
    names keeps its indices)."""
    if part.material_index is None or not part.material_names:
        return part.material_index
    where = np.array([names.index(n) for n in part.material_names], dtype=np.int64)
    return where[np.clip(np.asarray(part.material_index, np.int64), 0, len(where) - 1)]


def _spans_seam(uv, tri_loops, t_corner, b_corner, v, tris, corners):
    """(F,) bool: new triangles whose corners' UVs lie much farther apart than their
    positions, compared with the keyframe mesh's own UV-to-space scale: their corners
    landed on the two sides of a UV seam."""
    def uv_over_space(uv_tri, pos_tri):
        duv = np.linalg.norm(uv_tri - np.roll(uv_tri, 1, axis=1), axis=-1)
        dx = np.linalg.norm(pos_tri - np.roll(pos_tri, 1, axis=1), axis=-1)
        return duv, dx

    duv, dx = uv_over_space(uv[tri_loops], v[tris])
    scale = np.median(duv[dx > 0] / dx[dx > 0])
    own = np.einsum("fci,fcik->fck", b_corner, uv[tri_loops[t_corner]])
    duv, dx = uv_over_space(own, corners)
    return np.any(duv > 4.0 * scale * dx + 1e-6, axis=1)


def _plane_barycentric(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:

    """Barycentric coordinates of p projected onto the planes of (a, b, c), not clipped."""
    e0, e1, w = b - a, c - a, p - a
    d00, d01, d11 = (np.einsum("ij,ij->i", x, y) for x, y in ((e0, e0), (e0, e1), (e1, e1)))
    d20, d21 = np.einsum("ij,ij->i", w, e0), np.einsum("ij,ij->i", w, e1)
    det = d00 * d11 - d01 ** 2
    det = np.where(np.abs(det) > 0, det, 1.0)
    u = (d11 * d20 - d01 * d21) / det
    t = (d00 * d21 - d01 * d20) / det
    return np.stack([1.0 - u - t, u, t], axis=1)
