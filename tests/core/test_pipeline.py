"""End to end through `animate`: meshes + feature points + frames -> one tracked mesh per frame."""

import re

import numpy as np
import pytest

from inbetween_cases import rotation, sphere_features, turning_sphere, uv_sphere
from keyframe_implicit.core import Animation, Cancelled, Keyframe, animate, mesh_to_sdf, sample


def test_translated_sphere_every_frame_on_its_surface_and_keyframes_matched():
    r = 0.3
    va, fa = uv_sphere(np.zeros(3), r)
    off = np.array([0.4, 0.1, -0.2])
    R = rotation([0.3, 1.0, 0.2], np.deg2rad(50))
    vb = va @ R.T + off  # same sphere, rotated and moved: every in-between is that sphere
    pa, pb = sphere_features(np.zeros(3), r, R, off)
    seen = []
    anim = animate([Keyframe(va, fa, 1), Keyframe(vb, fa, 9)], [(pa, pb)], resolution=24,
                   progress=lambda f, m: seen.append(f))
    assert isinstance(anim, Animation)
    assert anim.frames.tolist() == list(range(1, 10))
    assert anim.vertices.shape[0] == 9 and anim.vertices.shape[2] == 3
    assert anim.faces.ndim == 2 and anim.faces.shape[1] == 3
    assert np.all(np.diff(seen) >= -1e-12) and seen[-1] == pytest.approx(1.0)
    h = anim.grid.spacing
    for i, f in enumerate(anim.frames):
        s = (f - 1) / 8.0
        centre = s * off
        dist = np.abs(np.linalg.norm(anim.vertices[i] - centre, axis=1) - r)
        assert dist.mean() <= 0.25 * h, (f, dist.mean() / h)
    # keyframe ends lie on the keyframe meshes' own distance grids
    phi_b = mesh_to_sdf(vb, fa, anim.grid)
    assert np.abs(sample(phi_b, anim.grid, anim.vertices[-1])).mean() <= 0.25 * h


def test_three_keyframes_one_template_through_all_frames():
    r = 0.25
    v0, f0 = uv_sphere(np.zeros(3), r, n=16)
    o1, o2 = np.array([0.3, 0.0, 0.0]), np.array([0.3, 0.3, 0.0])
    feats = [sphere_features(np.zeros(3), r, offset=o1),
             sphere_features(o1, r, offset=o2 - o1)]
    anim = animate([Keyframe(v0, f0, 0), Keyframe(v0 + o1, f0, 4), Keyframe(v0 + o2, f0, 8)],
                   feats, resolution=20)
    assert anim.frames.tolist() == list(range(0, 9))
    h = anim.grid.spacing
    mid = np.abs(np.linalg.norm(anim.vertices[4] - o1, axis=1) - r)
    assert mid.mean() <= 0.25 * h


def test_bad_input_says_what_to_fix():
    v, f = uv_sphere(np.zeros(3), 0.3, n=8)
    with pytest.raises(ValueError, match="at least two keyframes"):
        animate([Keyframe(v, f, 1)], [])
    with pytest.raises(ValueError, match="strictly increasing"):
        animate([Keyframe(v, f, 5), Keyframe(v, f, 5)], [(np.zeros((4, 3)), np.zeros((4, 3)))])
    with pytest.raises(ValueError, match="partner"):
        animate([Keyframe(v, f, 1), Keyframe(v, f, 5)], [(np.zeros((4, 3)), np.zeros((3, 3)))])
    with pytest.raises(ValueError, match="Unknown weight"):
        animate([Keyframe(v, f, 1), Keyframe(v, f, 5)], [(np.zeros((4, 3)), np.zeros((4, 3)))],
                weights={"inertia": 1.0})


def test_cancel_raises_cancelled():
    v, f = uv_sphere(np.zeros(3), 0.3, n=8)
    pa, pb = sphere_features(np.zeros(3), 0.3)
    calls = []

    def cancel():
        calls.append(1)
        return len(calls) > 2

    with pytest.raises(Cancelled):
        animate([Keyframe(v, f, 1), Keyframe(v, f, 5)], [(pa, pb)], resolution=16, cancel=cancel)


def test_too_large_a_grid_is_refused_before_any_work():
    from keyframe_implicit.core import MemoryLimitError

    v, f = uv_sphere(np.zeros(3), 0.3, n=8)
    pa, pb = sphere_features(np.zeros(3), 0.3)
    stages = []
    with pytest.raises(MemoryLimitError, match=r"lower the resolution to \d+") as err:
        animate([Keyframe(v, f, 1), Keyframe(v + 0.2, f, 5)], [(pa, pb + 0.2)], resolution=400,
                max_bytes=450 * 2**20, progress=lambda frac, msg: stages.append(msg))
    assert not any("Distance fields" in m for m in stages)  # refused before the first distance field
    best = err.value.max_resolution
    assert 4 <= best < 400
    animate([Keyframe(v, f, 1), Keyframe(v + 0.2, f, 5)], [(pa, pb + 0.2)], resolution=best,
            max_bytes=450 * 2**20)  # the resolution the message names does fit


def _cube(half=0.5):
    v = np.array([[x, y, z] for x in (-half, half) for y in (-half, half) for z in (-half, half)])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def test_the_grid_holds_a_turning_body_half_way_not_only_its_keyframes():
    """A cube turned a quarter turn has the same box on both keyframes; half-way its
    corners reach 41 % of its half-width past it. The grid holds that, whatever the
    padding (it is in cells, and shrinks with the resolution)."""
    v, f = _cube()
    rot = rotation((0.0, 0.0, 1.0), np.pi / 2)
    corners = v[[0, 3, 5, 6]]
    anim = animate([Keyframe(v, f, 1), Keyframe(v @ rot.T, f, 9)], [(corners, corners @ rot.T)],
                   resolution=12, padding_cells=1, template="grid")
    half_way = v @ rotation((0.0, 0.0, 1.0), np.pi / 4).T
    assert np.all(anim.grid.contains(half_way))
    lo, hi = anim.grid.origin, anim.grid.origin + anim.grid.spacing * (np.array(anim.grid.shape) - 1)
    assert hi[0] - lo[0] >= 2 * 0.5 * np.sqrt(2)  # not only the keyframes' 1.0 + padding


def _stages(messages):
    """{stage: its counts in the order reported} of messages "Stage i/n"."""
    out = {}
    for m in messages:
        stage, count = m.rsplit(" ", 1)
        out.setdefault(stage, []).append(tuple(map(int, count.split("/"))))
    return out


def test_progress_counts_the_artists_frames():
    """The frames a progress report counts are the animation's, from its first frame to its
    last, never a count within one segment ("frame 12 (12/13)" on a 25-frame animation)."""
    va, fa = uv_sphere(np.zeros(3), 0.3)
    kfs = [Keyframe(va, fa, 1), Keyframe(va + [0.3, 0, 0], fa, 4), Keyframe(va + [0.6, 0, 0], fa, 7)]
    seen = []
    animate(kfs, [(np.zeros((0, 3)), np.zeros((0, 3)))] * 2, resolution=16,
            progress=lambda f, m: seen.append(m))
    frames = [m for m in seen if m.startswith("Frames ")]
    assert sorted(set(frames), key=lambda m: int(m.split()[1].split("/")[0])) == [
        f"Frames {i}/7" for i in range(1, 8)], frames


def test_an_output_set_in_the_settings_is_the_only_one_made_and_measured(monkeypatch):
    """Auto makes both outputs and measures both; an output set in the settings makes that
    one alone, with the same figures, meshes and velocities as Auto's: shape keys neither
    the mesh sequence's figures nor the frames' velocities; a mesh sequence measures the
    template too, which says on which frames it ships the artist's mesh, and the last
    keyframe's own mesh tracked back on each frame (`chain._keyframe_tracks`)."""
    from keyframe_implicit.core.bake import chain
    from keyframe_implicit.core.motion.levelset import Inbetween

    kfs, feats = turning_sphere(n=16, last=5)
    calls = {"quality": 0, "velocity": 0}
    quality, velocity = chain.frame_quality, Inbetween.velocity

    def counted(name, f):
        def call(*args, **kwargs):
            calls[name] += 1
            return f(*args, **kwargs)
        return call

    monkeypatch.setattr(chain, "frame_quality", counted("quality", quality))
    monkeypatch.setattr(Inbetween, "velocity", counted("velocity", velocity))
    baked, counts = {}, {}
    for output in ("auto", "shape_keys", "mesh_sequence"):
        calls.update(quality=0, velocity=0)
        baked[output] = animate(kfs, feats, resolution=16, output=output)
        counts[output] = dict(calls)
    auto, keys, sequence = baked["auto"], baked["shape_keys"], baked["mesh_sequence"]
    frames = len(auto.frames)
    assert counts == {"auto": {"quality": 3 * frames, "velocity": frames},
                      "shape_keys": {"quality": frames, "velocity": 0},
                      "mesh_sequence": {"quality": 3 * frames, "velocity": frames}}
    assert set(auto.stats["quality"]) == {"shape_keys", "mesh_sequence"}
    assert keys.stats["quality"] == {"shape_keys": auto.stats["quality"]["shape_keys"]}
    assert sequence.stats["quality"] == auto.stats["quality"]  # the template's say where it ships
    assert keys.stats["output"] == "shape_keys" and sequence.stats["output"] == "mesh_sequence"
    for other in (keys, sequence):
        assert np.array_equal(other.vertices, auto.vertices)
    assert keys.surfaces == [] and keys.velocities == []
    for (v, t), (w, u) in zip(sequence.surfaces, auto.surfaces):
        assert np.array_equal(v, w) and np.array_equal(t, u)
    for v, w in zip(sequence.velocities, auto.velocities, strict=True):
        assert np.array_equal(v, w)
    with pytest.raises(ValueError, match="output must be one of"):
        animate(kfs, feats, resolution=16, output="both")


#: What a bake's progress says: counted steps of its stages, in the artist's words.
STEP = re.compile(r"^(Distance fields|Maps|Paths|Frames) (\d+)/(\d+)$")


@pytest.mark.parametrize("processes, interpolation", [(1, "smooth"), (2, "linear")])
def test_progress_is_counted_steps_and_never_goes_back(processes, interpolation):
    """Every message of a bake is a stage's count ("Maps 3/6"), each stage counted from 1
    to all its steps in order and the stages in the order they run; the fraction never
    goes back and ends at 1, with a helper process too."""
    va, fa = uv_sphere(np.zeros(3), 0.3)
    kfs = [Keyframe(va, fa, 1), Keyframe(va + [0.3, 0, 0], fa, 5), Keyframe(va + [0.6, 0, 0], fa, 9)]
    pa, pb = sphere_features(np.zeros(3), 0.3)
    feats = [(pa, pb + [0.3, 0, 0]), (pa + [0.3, 0, 0], pb + [0.6, 0, 0])]
    seen = []
    animate(kfs, feats, resolution=20, processes=processes, key_interpolation=interpolation,
            progress=lambda f, m: seen.append((f, m)))
    fractions = [f for f, _ in seen]
    messages = [m for _, m in seen]
    assert all(STEP.match(m) for m in messages), [m for m in messages if not STEP.match(m)]
    assert all(b >= a for a, b in zip(fractions, fractions[1:])), fractions
    assert fractions[0] == 0.0 and fractions[-1] == 1.0
    counted = _stages(messages)
    bends = interpolation != "linear"
    assert {stage: counts[-1] for stage, counts in counted.items()} == {
        "Distance fields": (3, 3), "Maps": (4, 4), "Paths": (2 + bends, 2 + bends),
        "Frames": (9, 9)}
    for stage, counts in counted.items():
        numbers = [i for i, _ in counts]
        assert numbers == sorted(numbers) and numbers[0] == 1, (stage, numbers)
        assert set(numbers) == set(range(1, counts[-1][1] + 1)), (stage, numbers)
    first = {stage: messages.index(f"{stage} 1/{counts[-1][1]}")
             for stage, counts in counted.items()}
    assert first["Distance fields"] < first["Maps"] < first["Paths"] < first["Frames"]
