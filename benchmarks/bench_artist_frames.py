"""Which frames ship the artist's mesh: a thin rod turning rigidly, and parts before contact.

    python benchmarks/bench_artist_frames.py [--rods 2.5 2 1.5] [--cases merge ...]

Every figure reads the output a default bake through `core.animate` ships
(``stats["output"]``), frame by frame, as `meshdata.output_mesh` lays it out for Blender.
A frame "ships the artist's mesh" when its mesh has a keyframe's polygons (the same
vertex count and corners) and its UVs: the first keyframe's, or where that no longer
follows, a keyframe's own mesh tracked from its frame into a segment beside it.

Rods: a box 30 h long and ``t`` h thick (2.5, 2 and 1.5) with a UV map turns a quarter
turn rigidly about the z axis through its centre while its centre moves on a straight line
to (c, c, 0), c = 33 - t/2 h; keyframes on frames 1 and 25, feature points on four of its
corners. The keyframes' box is then 48 h wide, so at resolution 48 (the default) the
bake's cell is h. Per frame: what ships ("artist", "surface", or on the last keyframe's
frame "key B", the artist's mesh of B), the two-way distance of the shipped mesh from the
exactly turned rod (angle s * 90 degrees, centre on its line; max and mean, in h), its
volume against the rod's, and the volume step from each keyframe frame to its neighbour;
then the same distance and volume of the tracked template (the shape keys).

Contact cases (`contact_cases.py`, baked as `bench_contact.py` bakes them): the frames
before contact (`contact_metrics.contact_frame` on the frames' own surfaces), and how many
of them ship the artist's mesh (its vertex count, and its UVs: every keyframe is given a
UV map here, its vertices' x and y), and of all frames; the frame the material's topology changes
(``stats["topology"]``, where the bake's tracked frames end at the latest), the template
pieces' largest volume drift since frame 1 before it (``stats["volumes"]``), the motion a frame
(the tracked template's largest vertex move from frame 2 to 3, in h), and the frame after
each keyframe but the last, and the frame before each but the first, against the
keyframe's frame: two-way distance max (h) and volume step. ``--slow K`` puts the keyframes K times as many frames apart, for the issue's
"slow motion" (under 0.5 h a frame).
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path[:0] = [os.path.dirname(HERE), HERE]

from keyframe_implicit.core import Keyframe, animate  # noqa: E402
from keyframe_implicit.core.surface.attributes import MeshAttributes  # noqa: E402
from keyframe_implicit.core.surface.extract import mesh_volume  # noqa: E402
from keyframe_implicit.core.surface.meshdata import FRAME_ATTRIBUTE, SHAPE_KEYS  # noqa: E402
from keyframe_implicit.core.surface.quality import keyframe_distance  # noqa: E402

ROD_LENGTH, ROD_BOX = 30.0, 48.0  # in h
ROD_FRAMES = (1, 25)
BOX_QUADS = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                      [1, 5, 7, 3]])


def rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def with_uvs(vertices: np.ndarray, attributes: MeshAttributes) -> MeshAttributes:
    """``attributes`` with a UV map "UVMap": each corner's vertex's x and y."""
    uv = np.asarray(vertices, dtype=np.float32)[attributes.loop_vertices][:, :2]
    attributes.uv_maps = {"UVMap": np.ascontiguousarray(uv)}
    return attributes


def rod(thickness: float, h: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The rod on keyframe A: along x from 18 - t/2 to 48 - t/2 (h), centred on y = z = 0;
    (8, 3) vertices and its six quads."""
    xs, half = (-ROD_LENGTH / 2, ROD_LENGTH / 2), thickness / 2
    v = np.array([[x, y, z] for x in xs for y in (-half, half) for z in (-half, half)])
    return v * h, BOX_QUADS


def rod_motion(thickness: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, translation) of the rod at time ``s``: turned ``s`` quarter turns about
    its centre, which moves on a straight line to (c, c, 0), c = 48 - 15 - t/2 (h)."""
    c = ROD_BOX - ROD_LENGTH / 2 - thickness / 2
    return rot_z(np.pi / 2 * s), np.array([c, c, 0.0]) * s


def rod_keyframes(thickness: float) -> tuple[list[Keyframe], list[tuple]]:
    """The rod's two keyframes (with UVs) and its feature pairs (four corners)."""
    v, quads = rod(thickness)
    turn, shift = rod_motion(thickness, 1.0)
    attrs = with_uvs(v, MeshAttributes(np.arange(0, 24, 4), np.full(6, 4), quads.reshape(-1)))
    corners = v[[7, 4, 2, 1]]
    kfs = [Keyframe(v, quads, ROD_FRAMES[0], "rod", attrs),
           Keyframe(v @ turn.T + shift, quads, ROD_FRAMES[1], "rod turned")]
    return kfs, [(corners, corners @ turn.T + shift)]


def shipped(anim) -> list[dict]:
    """Per frame, the mesh the bake ships: ``vertices``, ``triangles``, ``artist`` (its
    polygons are a keyframe's, with that keyframe's UVs: the first keyframe's on the
    template, a keyframe's own beside its frame)."""
    kind = anim.stats.get("output", SHAPE_KEYS)
    keys = anim.output_mesh(SHAPE_KEYS).polygons
    if kind == SHAPE_KEYS:
        tris = keys.triangles()
        return [dict(vertices=np.asarray(v, float), triangles=tris, artist=bool(keys.uv_maps))
                for v in anim.vertices]
    data = anim.output_mesh(kind)
    poly, which = data.polygons, data.face_ints[FRAME_ATTRIBUTE]
    tri_loops, tri_poly = poly.triangle_loops()
    uv = next(iter(poly.uv_maps.values()), None)
    artists = [keys] + [anim.keyframe_attributes[int(f)] for f in anim.frames
                        if int(f) in anim.keyframe_attributes][1:]
    out, first = [], 0
    for i in range(len(anim.frames)):
        mine = np.flatnonzero(which == i)
        loops = np.concatenate([np.arange(poly.loop_start[p], poly.loop_start[p] + poly.loop_total[p])
                                for p in mine])
        last = int(poly.loop_vertices[loops].max()) + 1
        corners = poly.loop_vertices[loops] - first

        def is_mesh_of(attrs):  # these polygons, with those UVs
            return (len(mine) == attrs.n_polygons
                    and np.array_equal(corners, attrs.loop_vertices) and uv is not None
                    and bool(attrs.uv_maps)
                    and np.allclose(uv[loops], next(iter(attrs.uv_maps.values())), atol=1e-5))
        tris = poly.loop_vertices[tri_loops[np.isin(tri_poly, mine)]] - first
        out.append(dict(vertices=np.asarray(data.positions[first:last], float), triangles=tris,
                        artist=any(is_mesh_of(a) for a in artists)))
        first = last
    return out


def rod_figures(thickness: float, resolution: int = 48) -> dict:
    """Bake the rod of ``thickness`` h; its per-frame figures in h (module docstring)."""
    kfs, feats = rod_keyframes(thickness)
    anim = animate(kfs, feats, resolution=resolution)
    h = anim.grid.spacing
    v, quads = rod(thickness)
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    volume = ROD_LENGTH * thickness ** 2
    f0, f1 = ROD_FRAMES
    rows = []
    for f, mesh in zip(anim.frames, shipped(anim)):
        turn, shift = rod_motion(thickness, (f - f0) / (f1 - f0))
        exact = v @ turn.T + shift
        d = keyframe_distance(mesh["vertices"], mesh["triangles"], exact, tris, h)
        keys = keyframe_distance(anim.vertices[f - f0], anim.faces, exact, tris, h)
        rows.append(dict(frame=int(f), artist=mesh["artist"], max=d["keyframe_max"],
                         mean=d["keyframe_mean"],
                         volume=abs(mesh_volume(mesh["vertices"], mesh["triangles"])) / h ** 3
                         / volume, keys_max=keys["keyframe_max"],
                         keys_volume=abs(mesh_volume(anim.vertices[f - f0], anim.faces))
                         / h ** 3 / volume))
    vols = [r["volume"] for r in rows]
    return dict(thickness=thickness, h=h, output=anim.stats.get("output"), rows=rows,
                steps=(abs(vols[1] - vols[0]) / vols[0], abs(vols[-2] - vols[-1]) / vols[-1]))


def print_rod(fig: dict) -> None:
    rows = fig["rows"]
    n_artist = sum(r["artist"] for r in rows)
    inner = rows[1:-1]
    print(f"rod {fig['thickness']} h: ships {fig['output']}, the artist's mesh on {n_artist} "
          f"of {len(rows)} frames; in-betweens: distance max {max(r['max'] for r in inner):.2f} h, "
          f"mean of means {np.mean([r['mean'] for r in inner]):.2f} h, volume "
          f"{min(r['volume'] for r in inner):.3f}-{max(r['volume'] for r in inner):.3f}; "
          f"volume step at the keyframes {100 * fig['steps'][0]:.1f} %, "
          f"{100 * fig['steps'][1]:.1f} %")
    print("  frame  ships    max h  mean h  volume   shape keys: max h  volume")
    for i, r in enumerate(rows):
        ships = "artist" if r["artist"] else "key B" if i == len(rows) - 1 else "surface"
        print(f"  {r['frame']:5d}  {ships:7s} {r['max']:6.2f} {r['mean']:7.2f}  {r['volume']:.3f}"
              f"   {r['keys_max']:17.2f}  {r['keys_volume']:.3f}")


def contact_figures(name: str, resolution: int = 48, slow: int = 1) -> dict:
    """Case ``name`` baked with a UV map on keyframe A, its keyframes ``slow`` times as many
    frames apart: frames before contact, how many of them ship the artist's mesh, and the
    frames either side of each keyframe against that keyframe's frame."""
    import bench_contact
    import contact_metrics as cm
    from contact_cases import make_contact_case

    case = make_contact_case(name, bench_contact.MESH_NODES)
    kfs = [Keyframe(k.vertices, k.faces, 1 + slow * (k.frame - 1), k.name, k.attributes)
           for k in bench_contact.keyframes(case)]
    kfs = [Keyframe(k.vertices, k.faces, k.frame, k.name,
                    with_uvs(k.vertices, MeshAttributes.from_triangles(k.faces))) for k in kfs]
    anim = animate(kfs, case.features, resolution=resolution, processes=1)
    h = anim.grid.spacing
    own = [(np.asarray(v, float), np.asarray(f, np.int64)) for v, f in anim.surfaces]
    parts = len(cm.mesh_pieces(*own[0]).outer)
    contact = cm.contact_frame(own, parts, h)
    meshes = shipped(anim)
    before = len(meshes) if contact is None else contact
    topology, volumes = anim.stats["topology"], anim.stats["volumes"]
    near = next((i for i, t in enumerate(topology) if tuple(t) != tuple(topology[0])),
                len(topology))
    def step(i, j):  # frame j against keyframe frame i: two-way max (h), volume step
        a, b = meshes[i], meshes[j]
        d = keyframe_distance(b["vertices"], b["triangles"], a["vertices"], a["triangles"], h)
        return (d["keyframe_max"], abs(mesh_volume(b["vertices"], b["triangles"])
                                       / mesh_volume(a["vertices"], a["triangles"]) - 1.0))
    keys = [int(np.flatnonzero(anim.frames == k.frame)[0]) for k in kfs]
    after, before_key = [step(i, i + 1) for i in keys[:-1]], [step(i, i - 1) for i in keys[1:]]
    motion = np.linalg.norm(anim.vertices[2] - anim.vertices[1], axis=1).max() / h
    return dict(case=name, output=anim.stats.get("output"), frames=len(meshes), contact=contact,
                before=before, artist=sum(m["artist"] for m in meshes[:before]),
                artist_all=sum(m["artist"] for m in meshes), near=near,
                drift=max(np.abs(v / volumes[0] - 1.0).max() for v in volumes[:near]),
                motion=motion, after=after, before_key=before_key)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rods", type=float, nargs="*", default=[2.5, 2.0, 1.5])
    ap.add_argument("--cases", nargs="*", default=["merge", "unequal-merge", "splash", "drop"])
    ap.add_argument("--resolution", type=int, default=48)
    ap.add_argument("--slow", type=int, default=1,
                    help="the contact cases' keyframes this many times as many frames apart")
    args = ap.parse_args()
    for t in args.rods:
        print_rod(rod_figures(t, args.resolution))
    if args.cases:
        print("case           ships          frames  contact  before  artist before  artist all"
              "  topology at  drift %  motion h  after each keyframe: max h, volume % | before")
    for name in args.cases:
        c = contact_figures(name, args.resolution, args.slow)
        after = "; ".join(f"{m:.2f}, {100 * v:.2f}" for m, v in c["after"])
        after += " | before: " + "; ".join(f"{m:.2f}, {100 * v:.2f}" for m, v in c["before_key"])
        print(f"{c['case']:14s} {c['output']:14s} {c['frames']:6d}  {str(c['contact']):7s} "
              f"{c['before']:6d}  {c['artist']:13d}  {c['artist_all']:10d}  {c['near']:11d}  "
              f"{100 * c['drift']:7.2f}  {c['motion']:8.2f}  {after}")

if __name__ == "__main__":
    main()
