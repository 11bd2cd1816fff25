"""The artist's mesh on every frame one mesh can follow: the frames of a mesh sequence
before a topology change are the tracked template, with the artist's polygons and UVs."""

import numpy as np
import pytest

from keyframe_implicit.core import Keyframe, animate
from keyframe_implicit.core.bake.chain import tracked_frames
from keyframe_implicit.core.surface.attributes import MeshAttributes
from keyframe_implicit.core.surface.extract import material_topology
from keyframe_implicit.core.surface.meshdata import FRAME_ATTRIBUTE, MESH_SEQUENCE
from keyframe_implicit.core.surface.quality import flipped_fraction

from test_artist_template import uv_sphere


def frame_meshes(data, n):
    """Per frame of a mesh sequence's `MeshData`: (vertex count, loop vertices from 0, UVs)."""
    poly, which = data.polygons, data.face_ints[FRAME_ATTRIBUTE]
    uv = poly.uv_maps.get("UVMap")
    out, first = [], 0
    for i in range(n):
        loops = np.concatenate([np.arange(poly.loop_start[p], poly.loop_start[p] + poly.loop_total[p])
                                for p in np.flatnonzero(which == i)])
        last = int(poly.loop_vertices[loops].max()) + 1
        out.append((last - first, poly.loop_vertices[loops] - first,
                    None if uv is None else uv[loops]))
        first = last
    return out


@pytest.fixture(scope="module")
def merge_bake():
    """Two UV spheres (two materials, a UV map) that meet half-way and end as one ball of
    their volume."""
    v, polys, attrs = uv_sphere(10, 0.3)
    n = len(v)
    both = np.vstack([v - [0.45, 0, 0], v + [0.45, 0, 0]])
    polys2 = list(polys) + [np.asarray(p) + n for p in polys]
    from keyframe_implicit.core.surface.attributes import concatenate
    attrs2 = concatenate([attrs, attrs], [n, n])
    big, big_polys, _ = uv_sphere(14, 0.3 * 2 ** (1 / 3))
    dirs = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]]) * 0.15
    fa = np.vstack([dirs - [0.45, 0, 0], dirs + [0.45, 0, 0]])
    fb = np.vstack([dirs - [0.16, 0, 0], dirs + [0.16, 0, 0]])
    kfs = [Keyframe(both, polys2, 1, "balls", attrs2), Keyframe(big, big_polys, 17, "ball")]
    return kfs, animate(kfs, [(fa, fb)], resolution=24)


def test_a_merge_ships_the_artists_mesh_on_every_frame_before_contact(merge_bake):
    """Every frame before the balls meet is the artist's mesh, each ball
    within 1 % of its volume (the offsets the tracking carries from the keyframes once
    swelled them by 2-3 % from the first in-between on)."""
    kfs, an = merge_bake
    attrs = kfs[0].attributes
    topo = an.stats["topology"]
    contact = next(i for i, t in enumerate(topo) if tuple(t) != tuple(topo[0]))
    assert an.stats["output"] == "mesh_sequence" and contact >= 4
    volumes = an.stats["volumes"]
    drift = [np.abs(v / volumes[0] - 1.0).max() for v in volumes[:contact]]
    assert max(drift) <= 0.01
    tracked = an.stats["tracked_frames"]
    assert tracked == contact
    frames = frame_meshes(an.output_mesh(MESH_SEQUENCE), len(an.frames))
    for count, loops, uv in frames[:tracked]:  # the artist's polygons and UVs
        assert count == len(kfs[0].vertices)
        np.testing.assert_array_equal(loops, attrs.loop_vertices)
        np.testing.assert_array_equal(uv, attrs.uv_maps["UVMap"])
    for count, _, _ in frames[tracked:-1]:  # then each frame's own surface
        assert count != len(kfs[0].vertices)


@pytest.fixture(scope="module")
def merge_then_move():
    """The two UV spheres meet in the first segment and end as one UV sphere of their
    volume on frame 13, which then moves 0.3 along x by frame 19."""
    v, polys, attrs = uv_sphere(8, 0.3)
    n = len(v)
    from keyframe_implicit.core.surface.attributes import concatenate
    both = Keyframe(np.vstack([v - [0.45, 0, 0], v + [0.45, 0, 0]]),
                    list(polys) + [np.asarray(p) + n for p in polys], 1, "balls",
                    concatenate([attrs, attrs], [n, n]))
    big, big_polys, big_attrs = uv_sphere(10, 0.3 * 2 ** (1 / 3))
    shift = np.array([0.3, 0.0, 0.0])
    dirs = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]]) * 0.15
    fa = np.vstack([dirs - [0.45, 0, 0], dirs + [0.45, 0, 0]])
    fb = np.vstack([dirs - [0.16, 0, 0], dirs + [0.16, 0, 0]])
    kfs = [both, Keyframe(big, big_polys, 13, "ball", big_attrs),
           Keyframe(big + shift, big_polys, 19, "ball moved", big_attrs)]
    return kfs, shift, animate(kfs, [(fa, fb), (fb, fb + shift)], resolution=24,
                               output="mesh_sequence")


def test_a_later_segment_that_keeps_its_topology_ships_its_keyframes_mesh(merge_then_move):
    """After the balls meet, the frames of the next segment are keyframe 2's own mesh,
    tracked (`animation.KeyframeTrack`): its polygons and UVs, carried rigidly along x,
    not each frame's own surface."""
    kfs, shift, an = merge_then_move
    big = kfs[1]
    attrs = big.attributes
    rows = np.flatnonzero((an.frames > 13) & (an.frames < 19))
    frames = frame_meshes(an.output_mesh(MESH_SEQUENCE), len(an.frames))
    assert not an.tracked[rows[0] - 1] and len(rows) == 5
    forward = [t for t in an.keyframe_tracks if t.step > 0]
    assert [t.ships for t in forward] == [5]
    h = an.grid.spacing
    travel = [0.0]
    for i in rows:
        count, loops, uv = frames[i]
        assert count == len(big.vertices)
        np.testing.assert_array_equal(loops, attrs.loop_vertices)
        np.testing.assert_array_equal(uv, attrs.uv_maps["UVMap"])
        moved = an.sequence_frame(i)[0] - big.vertices
        assert np.abs(moved - moved.mean(axis=0)).max() < 0.5 * h
        assert np.abs(moved.mean(axis=0)[1:]).max() < 0.1 * h
        travel.append(moved.mean(axis=0)[0])
        assert np.abs(an.sequence_velocity(i).mean(axis=0)[1:]).max() < 0.1 * h
    assert np.all(np.diff(travel + [shift[0]]) > 0)
    assert an.stats["keyframe_track_frames"] == sum(t.ships for t in an.keyframe_tracks)
    artist = sum(an.sequence_frame(i)[1] is not an.surfaces[i][1] for i in range(len(an.frames)))
    assert an.stats["output_reason"].endswith(f"the artist's mesh on {artist + 2} of 19 frames")


def test_a_template_that_follows_on_leaves_the_keyframe_tracks_unshipped():
    """A ball moving through three keyframes keeps the first keyframe's mesh throughout:
    the keyframes' own meshes, tracked into the segments next to them, ship on no frame."""
    v, polys, attrs = uv_sphere(8, 0.3)
    step = np.array([0.2, 0.0, 0.0])
    kfs = [Keyframe(v + k * step, polys, 1 + 4 * k, f"ball {k}", attrs) for k in range(3)]
    pts = np.array([[0, 0, 0], [0, 0.15, 0], [0, 0, 0.15], [0.15, 0, 0]])
    an = animate(kfs, [(pts, pts + step), (pts + step, pts + 2 * step)], resolution=20,
                 output="mesh_sequence")
    assert len(an.keyframe_tracks) == 3 and not any(t.ships for t in an.keyframe_tracks)
    assert an.stats["tracked_frames"] == len(an.frames) - 2  # but for keyframes 2 and 3


def marching_cubes_balls(radii, centres, ends, resolution):
    """Balls of ``radii`` at x = ``centres`` that merge into one ball of their volume, their
    centres going to x = ``ends``, feature points on a cross about each; the keyframes are
    marching-cubes meshes (slivers a small fraction of a cell high, as a sculpt's remesh
    leaves), baked as a mesh sequence on frames 1 and 17."""
    from keyframe_implicit.core.base.grid import Grid
    from keyframe_implicit.core.surface.extract import extract_surface
    from keyframe_implicit.shapes import sphere_sdf

    grid = Grid(np.full(3, -1.0), 2.0 / 96, (97,) * 3)
    x = grid.points()
    at = [np.array([c, 0.0, 0.0]) for c in centres]
    a = extract_surface(np.minimum(*(sphere_sdf(x, c, r) for c, r in zip(at, radii))), grid)
    b = extract_surface(sphere_sdf(x, (0, 0, 0), np.cbrt(np.sum(np.power(radii, 3)))), grid)
    cross = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]])
    fa = np.vstack([c + 0.5 * r * cross for c, r in zip(at, radii)])
    fb = np.vstack([[e, 0, 0] + 0.5 * r * cross for e, r in zip(ends, radii)])
    return animate([Keyframe(*a, 1, "balls"), Keyframe(*b, 17, "ball")], [(fa, fb)],
                   resolution=resolution, output="mesh_sequence")


@pytest.fixture(scope="module")
def marching_cubes_merge():
    """Two equal balls, at 48."""
    return marching_cubes_balls((0.3, 0.3), (-0.4, 0.4), (-0.15, 0.15), 48)


@pytest.fixture(scope="module")
def unequal_marching_cubes_merge():
    """A ball and one of 2/3 its radius, at 32."""
    return marching_cubes_balls((0.3, 0.2), (-0.35, 0.4), (-0.1, 0.15), 32)


def test_marching_cubes_keyframes_are_tracked_until_contact(unequal_marching_cubes_merge):
    """Every frame before the balls' own surfaces join is the artist's mesh. Each ball's
    volume is held by scaling it, which turns no face: an offset along the vertex normals
    turned the slivers from frame 2, and the fold guard then ended the artist's mesh
    there. Tracking once also stopped two cells short of contact."""
    from keyframe_implicit.core.surface.extract import mesh_pieces

    an = unequal_marching_cubes_merge
    contact = next(i for i, (v, f) in enumerate(an.surfaces) if mesh_pieces(f, len(v))[0] < 2)
    assert contact >= 5
    assert an.stats["tracked_frames"] == contact
    for v in an.vertices[:contact]:
        assert flipped_fraction(an.vertices[0], v, an.faces) == 0.0


def test_tracked_frames_keep_to_their_own_surfaces_as_parts_approach(marching_cubes_merge):
    """The zero set steers the whole of a ball that deforms anywhere: steered only where its
    paths stretch (the side facing the other ball), each ball drew a lip there from frame 4,
    over a cell off the frame's own surface by frame 6."""
    from keyframe_implicit.core.surface.quality import mesh_distance

    an = marching_cubes_merge
    h = an.grid.spacing
    for i in range(an.stats["tracked_frames"]):
        assert mesh_distance(an.vertices[i], *an.surfaces[i]).max() < 0.5 * h


def test_the_frame_after_a_keyframe_moves_from_it_as_its_paths_do(unequal_marching_cubes_merge):
    """The keyframes' offsets trade places from rest, so frame 2 is off keyframe A by
    about the motion of a frame (here under half a cell), not by that plus a 16th of the
    way to B's landing points."""
    from keyframe_implicit.core.surface.quality import keyframe_distance

    an = unequal_marching_cubes_merge
    h = an.grid.spacing
    step = keyframe_distance(an.vertices[1], an.faces, an.vertices[0], an.faces, h)
    motion = np.linalg.norm(an.vertices[2] - an.vertices[1], axis=1).max() / h
    assert motion < 0.5
    assert step["keyframe_max"] <= motion + 0.05


def test_paths_that_end_deep_inside_b_land_late():
    """An unequal merge whose big ball's facing side ends some 10 cells inside the merged
    ball: its closest points on B are that far from where its paths end. The frames before
    contact keep to the paths (within 1.5 cells at a quarter of the way; closing that gap
    as the offsets trade places moved them 1.85 cells there)."""
    from keyframe_implicit.core import inbetween
    from keyframe_implicit.core.base.grid import Grid
    from keyframe_implicit.core.surface.extract import extract_surface
    from keyframe_implicit.core.surface.template import DetailTrack
    from keyframe_implicit.shapes import sphere_sdf

    grid = Grid(np.full(3, -0.7), 1.4 / 48, (49,) * 3)
    x = grid.points()
    big, small = (np.array([-0.3, 0.0, 0.0]), 0.3), (np.array([0.4, 0.0, 0.0]), 0.2)
    phi_a = np.minimum(sphere_sdf(x, *big), sphere_sdf(x, *small))
    phi_b = sphere_sdf(x, (0, 0, 0), (0.3 ** 3 + 0.2 ** 3) ** (1 / 3))
    cross = np.array([[0, 0, 0], [0, 1, 0], [0, 0, 1], [0, -1, 0]])
    fa = np.vstack([big[0] + 0.15 * cross, small[0] + 0.1 * cross])
    fb = np.vstack([(-0.05, 0, 0) + 0.15 * cross, (0.15, 0, 0) + 0.1 * cross])
    inb = inbetween(phi_a, phi_b, grid, fa, fb)
    va, ta = extract_surface(phi_a, grid)
    track = DetailTrack(inb, va, ta, extract_surface(phi_b, grid))
    h = grid.spacing
    assert (np.linalg.norm(track.end - inb.trajectory(va, 1.0), axis=1) / h).max() > 8.0
    off_path = np.linalg.norm(track(0.25)[0] - inb.trajectory(va, 0.25), axis=1) / h
    assert off_path.max() < 1.5


@pytest.fixture(scope="module")
def rod_sequence():
    """The 2-cell rod of `test_thin_rod_turning_rigidly_stays_the_artists_mesh` baked as a
    mesh sequence: every frame is its tracked template."""
    v, quads = rod(12.0, 2.0)
    shift = np.array([1.0, 1.0, 0.0]) * (24 - 6.0 - 1.0)
    corners = v[[7, 4, 2, 1]]
    kfs = [Keyframe(v, quads, 1, "rod"), Keyframe(turned(v, 1.0, shift), quads, 13, "turned")]
    return animate(kfs, [(corners, turned(corners, 1.0, shift))], resolution=24,
                   output="mesh_sequence")


def test_tracked_frames_move_with_the_template(rod_sequence):
    an = rod_sequence
    assert an.stats["tracked_frames"] >= 2
    data = an.output_mesh(MESH_SEQUENCE)
    n = len(an.vertices[0])
    velocity = data.point_vectors["velocity"]
    np.testing.assert_allclose(velocity[n:2 * n], 0.5 * (an.vertices[2] - an.vertices[0]),
                               atol=1e-6)
    np.testing.assert_allclose(data.positions[n:2 * n], an.vertices[1])


def test_the_switch_is_at_the_topology_change_or_the_first_fold():
    frames = np.arange(1, 7)
    clean = {"area_ratio": 1.0, "inverted_fraction": 0.0, "coverage": 1.0}
    topo = [(2, 4)] * 4 + [(1, 2)] * 2
    assert tracked_frames(frames, [dict(clean) for _ in frames], topo).tolist() == [
        True] * 4 + [False] * 2
    folded = [dict(clean) for _ in frames]
    folded[2]["inverted_fraction"] = 0.02
    assert tracked_frames(frames, folded, topo).sum() == 2
    behind = [dict(clean, coverage=0.9) for _ in frames]  # the surface reaching ahead
    assert tracked_frames(frames, behind, topo).sum() == 4
    assert tracked_frames(frames, [dict(clean, area_ratio=1.1) for _ in frames], topo).sum() == 4
    volumes = [np.array([1.0, 2.0])] * 6
    volumes[3] = np.array([1.0, 2.05])  # a piece swells by 2.5 %
    assert tracked_frames(frames, [dict(clean) for _ in frames], topo, volumes=volumes).sum() == 3
    turned = [0.0, 0.0, 0.001, 0.0, 0.0, 0.0]  # one small face turned over on frame 3
    assert tracked_frames(frames, [dict(clean) for _ in frames], topo, flipped=turned).sum() == 2


def test_flipped_fraction_is_the_area_turned_over_since_the_first_frame():
    start = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], float)
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    assert flipped_fraction(start, start + 0.3, faces) == 0.0  # moved, not turned
    folded = start.copy()
    folded[3] = [-1.0, -1.0, 0.0]  # the second triangle turned over, three times its area
    assert flipped_fraction(start, folded, faces) == pytest.approx(0.75)


def test_unfold_keeps_a_sliver_from_turning_over():
    """A sliver a thousandth of its length high, between two broad faces: offsets that
    differ by a hundredth across it turn it; unfolded, its corners share their mean offset,
    and the vertices of no turned face keep theirs."""
    from keyframe_implicit.core.surface.template import unfold

    start = np.array([[0, 0, 0], [1, 0, 0], [0.5, 0.001, 0], [0.5, -1, 0], [0.5, 1, 0],
                      [3, 0, 0]], float)
    faces = np.array([[0, 1, 2], [0, 3, 1], [2, 1, 4], [1, 3, 5]])
    offset = np.zeros((6, 3))
    offset[2, 1] = -0.01  # the apex crosses the sliver's base
    assert flipped_fraction(start, start + offset, faces) > 0.0
    out = unfold(start, faces, start, offset)
    assert flipped_fraction(start, start + out, faces) == 0.0
    np.testing.assert_allclose(out[[0, 1, 2]], np.tile(offset[[0, 1, 2]].mean(0), (3, 1)))
    np.testing.assert_array_equal(out[3:], offset[3:])


def test_material_topology_counts_pieces_and_holes():
    x, y, z = np.mgrid[-1:1:41j, -1:1:41j, -1:1:41j]  # cells of 0.05
    ball = np.sqrt(x ** 2 + y ** 2 + z ** 2) - 0.4
    assert material_topology(ball) == (1, 1)

    def two(radius):
        return np.minimum(np.sqrt((x - 0.5) ** 2 + y ** 2 + z ** 2),
                          np.sqrt((x + 0.5) ** 2 + y ** 2 + z ** 2)) - radius

    assert material_topology(two(0.3)) == (2, 2)  # 8 cells apart
    assert material_topology(two(0.48)) == (2, 2)  # a cell apart: still two
    assert material_topology(two(0.52)) == (1, 1)  # met
    torus = np.hypot(np.hypot(x, y) - 0.5, z) - 0.2
    assert material_topology(torus) == (1, 0)


def rod(length, thickness):
    """A box along x, centred on the origin: 8 vertices, six quads."""
    half = np.array([length, thickness, thickness]) / 2
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    return v, np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4],
                        [1, 5, 7, 3]])


def turned(v, s, shift):
    c, sn = np.cos(np.pi / 2 * s), np.sin(np.pi / 2 * s)
    return v @ np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1.0]]).T + s * shift


@pytest.mark.parametrize("thickness", [2.0, 1.5])
def test_thin_rod_turning_rigidly_stays_the_artists_mesh(thickness):
    """A rod 12 cells long and 1.5-2 cells thick turns a quarter turn while its centre
    moves on a line, the keyframes' box 24 cells wide at resolution 24: every frame is
    the artist's box, turned exactly, its volume kept; and each frame's own surface holds
    the box's volume too, where the grid's surface of the keyframes holds a fifth to a
    half less."""
    from keyframe_implicit.core.surface.extract import mesh_volume
    from keyframe_implicit.core.surface.quality import keyframe_distance

    length = 12.0
    v, quads = rod(length, thickness)
    shift = np.array([1.0, 1.0, 0.0]) * (24 - length / 2 - thickness / 2)
    corners = v[[7, 4, 2, 1]]
    kfs = [Keyframe(v, quads, 1, "rod"), Keyframe(turned(v, 1.0, shift), quads, 13, "turned")]
    an = animate(kfs, [(corners, turned(corners, 1.0, shift))], resolution=24)
    h = an.grid.spacing
    assert h == pytest.approx(1.0)
    assert an.stats["output"] == "shape_keys"
    tris = an.attributes.triangles()
    np.testing.assert_array_equal(an.faces, tris)
    for i, f in enumerate(an.frames):
        exact = turned(v, (f - 1) / 12, shift)
        assert keyframe_distance(an.vertices[i], tris, exact, tris, h)["keyframe_max"] < 0.1
        assert mesh_volume(an.vertices[i], tris) == pytest.approx(length * thickness ** 2, rel=0.01)
        # the frame's own surface holds the volume as modelled (within the iso-value's few
        # steps), not the grid's
        assert mesh_volume(*an.surfaces[i]) == pytest.approx(length * thickness ** 2, rel=0.02)


def test_tracked_frames_turn_the_custom_normals_with_their_faces():
    from keyframe_implicit.core.bake.animation import Animation

    v, quads = rod(4.0, 1.0)
    attrs = MeshAttributes(np.arange(0, 24, 4), np.full(6, 4), quads.reshape(-1))
    attrs.custom_normals = np.tile([[0.0, 0.6, 0.8]], (24, 1)).astype(np.float32)
    frames = [v, turned(v, 1.0, np.zeros(3))]
    an = Animation(np.array([1, 2]), np.stack(frames), attrs.triangles(), None,
                   surfaces=[(v, attrs.triangles())] * 2, velocities=[np.zeros_like(v)] * 2,
                   attributes=attrs, tracked=np.array([True, True]))
    assert an.sequence_attributes(0) is attrs
    np.testing.assert_allclose(an.sequence_attributes(1).custom_normals,
                               np.tile([[-0.6, 0.0, 0.8]], (24, 1)), atol=1e-6)


def test_the_frames_before_a_keyframe_lead_into_its_own_mesh(marching_cubes_merge):
    """Once the balls have met, the frames just before keyframe B are B's own mesh tracked
    back along its paths (`animation.KeyframeTrack`, step -1), not each frame's own
    surface, so nothing switches at B's frame; only as long as the tracked mesh gains no
    ripple a render would show (`chain.TRACK_RIPPLE`: further back, 0.3 cells)."""
    from keyframe_implicit.core.bake.chain import TRACK_RIPPLE
    from keyframe_implicit.core.surface.quality import keyframe_distance

    an = marching_cubes_merge
    back = [t for t in an.keyframe_tracks if t.step < 0]
    assert len(back) == 1 and back[0].ships >= 2
    track, last = back[0], len(an.frames) - 1
    key = an.surfaces[last]
    assert track.key_row == last and len(track.vertices[-1]) == len(key[0])
    for i in range(last - track.ships, last):
        v, f = an.sequence_frame(i)
        assert len(v) == len(key[0]) and np.array_equal(f, key[1])
        assert track.figures[i - track.first_row]["ripple"] <= TRACK_RIPPLE
        assert not an.is_tracked(i)
    h = an.grid.spacing
    before = keyframe_distance(*an.sequence_frame(last - 1), *key, h)
    after_own = keyframe_distance(*an.surfaces[last - 1], *key, h)
    assert before["keyframe_max"] < after_own["keyframe_max"]
    step = an.sequence_velocity(last - 1)
    moved = np.asarray(key[0], float) - np.asarray(an.sequence_frame(last - 2)[0], float)
    np.testing.assert_allclose(step, moved / 2, atol=1e-6)


def test_ripple_counts_rings_not_shape():
    """`quality.ripple` under a two-cell filter sees rings of a cell and a half on a ball,
    and hardly a change of its shape at the scale of the ball (stretched by a fifth):
    what `template.DetailTrack.ripple` counts."""
    from keyframe_implicit.core.base.grid import Grid
    from keyframe_implicit.core.surface.extract import extract_surface
    from keyframe_implicit.core.surface.quality import fine_detail, ripple
    from keyframe_implicit.core.surface.template import surface_filter
    from keyframe_implicit.shapes import sphere_sdf

    grid = Grid(np.full(3, -1.0), 0.02, (101,) * 3)
    v, f = extract_surface(sphere_sdf(grid.points(), (0, 0, 0), 0.6), grid)
    h = 0.05  # the bake's cell: the mesh is finer, as an artist's is
    smooth = surface_filter(v, 2.0 * h)
    n = v / np.linalg.norm(v, axis=1, keepdims=True)
    rings = v + 0.05 * h * np.sin(2 * np.pi * v[:, 2:] / (1.5 * h)) * n
    start = fine_detail(v, f, smooth)
    assert ripple(start, rings, f, smooth) / h > 0.02
    assert ripple(start, v * [1.2, 1.0, 1.0], f, smooth) / h < 0.002
    assert ripple(start, v, f, smooth) == 0.0
