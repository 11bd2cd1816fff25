"""The baked output's mesh as the arrays Blender stores, made outside Blender's main loop.

Blender keeps a mesh as attributes: point positions, each corner's vertex and edge, each
edge's two vertices, each face's first corner. Written through those attributes, every
array is one copy; written through ``mesh.vertices`` / ``mesh.loops`` it is one property
call per element, and ``mesh.update(calc_edges=True)`` builds the edges on the main
thread. `MeshData` holds everything the output mesh needs, edges included, so the worker
process makes it (`output_mesh`) and Blender's main loop only copies it in
(``blender/output.py``), in steps short enough for the interface to stay live.

Two outputs (`resolve_output`): shape keys (the tracked template's first frame; its frames
become shape keys) or a mesh sequence (every frame's own surface laid end to end, with the
face attribute naming the frame and each point's velocity).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from .attributes import MeshAttributes, concatenate

if TYPE_CHECKING:
    from collections.abc import Mapping
    from typing import Protocol

    from numpy.typing import ArrayLike

    class Baked(Protocol):
        """What `output_mesh` reads of a bake's result (`core.bake.animation.Animation`),
        named here so that this stage need not know the bake's module."""

        frames: np.ndarray
        vertices: np.ndarray
        faces: np.ndarray
        surfaces: list[tuple[np.ndarray, np.ndarray]]
        attributes: MeshAttributes | None

        def sequence_frame(self, i: int) -> tuple[np.ndarray, np.ndarray]: ...

        def sequence_velocity(self, i: int) -> np.ndarray: ...

        def sequence_attributes(self, i: int) -> MeshAttributes | None: ...

__all__ = ["MeshData", "polygon_edges", "match_edges", "resolve_output", "output_mesh"]

SHAPE_KEYS, MESH_SEQUENCE = "shape_keys", "mesh_sequence"
FRAME_ATTRIBUTE = "kfi_frame"  # the sequence's face attribute: the frame's index


@dataclass
class MeshData:
    """One Blender mesh as plain arrays.

    positions : (V, 3) float32, the points.
    polygons : `attributes.MeshAttributes`, the faces (corners, UVs, colours, materials,
        smooth flags, custom normals), their corner arrays int32 as Blender stores them;
        its own ``edges`` / flags are not used here.
    edges : (E, 2) int32, each edge's vertices, every edge once.
    corner_edges : (L,) int32, the edge from each corner to the next corner of its face.
    sharp_edges, seams : (E,) bool or None, the flags on ``edges``.
    face_ints : dict name -> (P,) int32, integer face attributes (the sequence's frame).
    point_vectors : dict name -> (V, 3) float32, vector point attributes (velocity per frame).
    """

    positions: np.ndarray
    polygons: MeshAttributes
    edges: np.ndarray
    corner_edges: np.ndarray
    sharp_edges: np.ndarray | None = None
    seams: np.ndarray | None = None
    face_ints: dict[str, np.ndarray] = field(default_factory=dict)
    point_vectors: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def build(cls, vertices: ArrayLike, polygons: MeshAttributes) -> MeshData:
        """The mesh of ``vertices`` (V, 3) and ``polygons`` (`MeshAttributes`): edges made
        with `polygon_edges`, the polygons' sharp and seam flags carried onto them."""
        edges, corner_edges = polygon_edges(polygons.loop_start, polygons.loop_total,
                                            polygons.loop_vertices)
        polygons = replace(polygons, **{name: np.asarray(getattr(polygons, name), np.int32)
                                        for name in ("loop_start", "loop_total", "loop_vertices")})
        data = cls(np.ascontiguousarray(vertices, dtype=np.float32).reshape(-1, 3), polygons,
                   edges, corner_edges)
        if polygons.edges is not None:
            rows = match_edges(edges, polygons.edges)
            data.sharp_edges = _flags_on(rows, polygons.sharp_edges)
            data.seams = _flags_on(rows, polygons.seams)
        return data


def _flags_on(rows: np.ndarray, flags: ArrayLike | None) -> np.ndarray | None:
    """Flags of source edges on the edges at ``rows`` (-1: no source edge, unflagged)."""
    if flags is None:
        return None
    out = np.zeros(len(rows), dtype=bool)
    out[rows >= 0] = np.asarray(flags, dtype=bool)[rows[rows >= 0]]
    return out if out.any() else None


def polygon_edges(loop_start: ArrayLike, loop_total: ArrayLike,
                  loop_vertices: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Every edge of the polygons once, and each corner's edge, as Blender stores them.

    Corner c of a polygon runs from its vertex to the next corner's (the last corner back to
    the first). An edge is an unordered vertex pair, so two polygons sharing a side share
    its edge.

    Returns
    -------
    edges : (E, 2) int32, the vertex pairs (smaller index first), sorted.
    corner_edges : (L,) int32, the row of ``edges`` each corner starts.
    """
    start = np.asarray(loop_start, dtype=np.int64)
    total = np.asarray(loop_total, dtype=np.int64)
    verts = np.asarray(loop_vertices, dtype=np.int64)
    nxt = np.arange(1, len(verts) + 1)
    nxt[start + total - 1] = start  # the last corner closes its polygon
    a, b = verts, verts[nxt]
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    width = int(verts.max(initial=-1)) + 1
    keys, corner_edges = np.unique(lo * width + hi, return_inverse=True)
    edges = np.stack([keys // max(width, 1), keys % max(width, 1)], axis=1)
    return edges.astype(np.int32), corner_edges.astype(np.int32).reshape(-1)


def match_edges(edges: ArrayLike, source: ArrayLike) -> np.ndarray:
    """Row of ``source`` (E_s, 2) holding each edge of ``edges`` (E, 2) (either order), or -1."""
    edges = np.reshape(edges, (-1, 2))
    source = np.reshape(source, (-1, 2))
    scale = int(max(np.max(edges, initial=0), np.max(source, initial=0))) + 1

    def key(e: np.ndarray) -> np.ndarray:
        e = np.sort(np.asarray(e, dtype=np.int64), axis=1)
        return e[:, 0] * scale + e[:, 1]
    src = key(source)
    order = np.argsort(src)
    want = key(edges)
    pos = np.clip(np.searchsorted(src[order], want), 0, max(len(src) - 1, 0))
    found = (len(src) > 0) & (src[order][pos] == want)
    return np.where(found, order[pos], -1)


def resolve_output(mode: str, stats: Mapping[str, Any]) -> tuple[str, str]:
    """(`SHAPE_KEYS` | `MESH_SEQUENCE`, reason) for the setting ``mode`` (AUTO, SHAPE_KEYS,
    MESH_SEQUENCE) and the core's figures (``Animation.stats``)."""
    if mode == "SHAPE_KEYS":
        return SHAPE_KEYS, "chosen in the output settings"
    if mode == "MESH_SEQUENCE":
        return MESH_SEQUENCE, "chosen in the output settings"
    if "output" in stats:
        return stats["output"], stats.get("output_reason", "")
    return SHAPE_KEYS, "no per-frame surfaces to choose from"


def clean_faces(faces: ArrayLike) -> np.ndarray:
    """(F, 3) triangles without the degenerate ones (a vertex twice)."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])
    return faces[keep]


def output_mesh(animation: Baked, kind: str) -> MeshData:

    """The `MeshData` of ``animation``'s output ``kind``.

    Shape keys: the template on the first frame, with the artist's polygons and attributes
    when the template is their mesh. Mesh sequence: every frame's mesh one after another
    (`Animation.sequence_frame`: the tracked template before a topology change, else the
    frame's own surface), with the face attribute `FRAME_ATTRIBUTE` (the frame's index)
    and the point attribute ``"velocity"`` (world units per frame); each frame carries its
    attributes (`Animation.sequence_attributes`: the artist's own on a tracked frame, else
    transferred from the artist's mesh), or else its triangles without the degenerate ones.
    """
    if kind == SHAPE_KEYS:
        polygons = animation.attributes
        if polygons is None:
            polygons = MeshAttributes.from_triangles(clean_faces(animation.faces))
        return MeshData.build(np.asarray(animation.vertices)[0], polygons)
    if kind != MESH_SEQUENCE:
        raise ValueError(f"unknown output {kind!r}: expected {SHAPE_KEYS!r} or {MESH_SEQUENCE!r}.")
    n = len(np.asarray(animation.frames).reshape(-1))
    if len(animation.surfaces) != n:
        raise ValueError("This bake holds no per-frame surfaces: choose Shape Keys as the output.")
    meshes = [animation.sequence_frame(i) for i in range(n)]
    per_frame = [animation.sequence_attributes(i) for i in range(n)]
    parts = [a if a is not None else MeshAttributes.from_triangles(clean_faces(faces))
             for (_, faces), a in zip(meshes, per_frame)]
    counts = [len(np.reshape(v, (-1, 3))) for v, _ in meshes]
    data = MeshData.build(np.concatenate([np.reshape(v, (-1, 3)) for v, _ in meshes]),
                          concatenate(parts, counts))
    data.face_ints[FRAME_ATTRIBUTE] = np.repeat(np.arange(len(parts), dtype=np.int32),
                                            [p.n_polygons for p in parts])
    data.point_vectors["velocity"] = np.concatenate(
        [np.reshape(animation.sequence_velocity(i), (-1, 3)) for i in range(n)]
    ).astype(np.float32)
    return data
