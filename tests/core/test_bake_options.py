"""A bake's options (`BakeOptions`): each keyword reaches the one stage that reads it, an
unknown one is refused before any work, a farm job keeps them whole, and the map solve and
the in-betweens take their options one way at a time."""

import numpy as np
import pytest

from inbetween_cases import nudged_spheres, unit_grid
from keyframe_implicit.core import Inbetween, Keyframe, animate, solve_map
from keyframe_implicit.core.bake.options import BakeOptions
from keyframe_implicit.core.map.options import MapOptions
from keyframe_implicit.core.motion.options import MotionOptions
from keyframe_implicit.farm import store


def test_each_keyword_reaches_the_stage_that_reads_it():
    options = BakeOptions.from_keywords(resolution=30, processes=2, coverage=False,
                                        transport="one-sided", margin_cells=2.0,
                                        volume_weight=5.0, weights={"rigidity": 3.0})
    assert (options.resolution, options.processes) == (30, 2)
    assert options.surface.coverage is False and options.surface.surfaces is True
    assert options.motion == MotionOptions(transport="one-sided")
    assert options.map.margin_cells == 2.0
    assert options.map.weights == dict(MapOptions().weights, volume=5.0, rigidity=3.0)
    # ``weights`` is the panel's form of the same weights, and wins over the keyword
    assert BakeOptions.from_keywords(volume_weight=5.0, weights={"volume": 7.0}).map.weights[
        "volume"] == 7.0
    assert BakeOptions.from_keywords() == BakeOptions()
    # ``template`` is animate's keyword for the field that says which mesh is tracked
    assert BakeOptions.from_keywords(template="grid").tracked_mesh == "grid"
    with pytest.raises(ValueError, match="unknown option 'tracked_mesh'"):
        BakeOptions.from_keywords(tracked_mesh="grid")


def test_an_unknown_option_is_refused_before_any_work():
    reported = []
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    with pytest.raises(ValueError, match=r"unknown option 'volume_wieght'; known options: .*"
                                         r"'resolution'.*'transport'.*'volume_weight'"):
        animate([Keyframe(v, f, 1), Keyframe(v, f, 5)], [(np.zeros((0, 3)),) * 2],
                volume_wieght=1.0, progress=lambda fraction, message: reported.append(message))
    assert reported == []
    with pytest.raises(ValueError, match="Unknown weight 'inertia'"):
        BakeOptions.from_keywords(weights={"inertia": 1.0})


def test_surface_tension_is_one_for_every_segment_or_one_per_segment():
    default = BakeOptions().motion.surface_tension
    assert [m.surface_tension for m in BakeOptions().segment_motion(2)] == [default] * 2
    options = BakeOptions.from_keywords(surface_tension=[0.0, 2.0])
    assert [m.surface_tension for m in options.segment_motion(2)] == [0.0, 2.0]
    assert options.motion.surface_tension == default  # the per-segment values are the bake's
    assert [m.surface_tension for m in
            BakeOptions.from_keywords(surface_tension=0.5).segment_motion(3)] == [0.5] * 3
    with pytest.raises(ValueError, match=r"one value per segment \(3\), got 2"):
        options.segment_motion(3)
    with pytest.raises(ValueError, match="surface_tension must be 0 or more"):
        BakeOptions.from_keywords(surface_tension=[-1.0]).segment_motion(1)
    reported = []
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]
    with pytest.raises(ValueError, match="one value per segment"):  # before any work
        animate([Keyframe(v, f, 1), Keyframe(v, f, 5)], [(np.zeros((0, 3)),) * 2],
                surface_tension=[1.0, 1.0], progress=lambda *a: reported.append(a))
    assert reported == []


def test_a_farm_job_file_keeps_the_options_whole(tmp_path):
    options = BakeOptions.from_keywords(resolution=20, motion_resolution=10,
                                        key_interpolation=["smooth", "ease"], levelsets=True,
                                        transport="one-sided", patch_rigidity=3.0)
    path = str(tmp_path / "options.npz")
    store.save(path, {"options": options})
    assert store.load(path)["options"] == options


def test_the_map_solve_and_the_inbetweens_take_options_one_way_at_a_time():
    g = unit_grid(2, 12)
    phi_a, phi_b = nudged_spheres(g)
    none = np.zeros((0, 2))
    with pytest.raises(TypeError, match="not both"):
        solve_map(phi_a, phi_b, g, none, none, options=MapOptions(), tolerance=0.1)
    with pytest.raises(TypeError, match="not both"):
        Inbetween.from_map(phi_a, phi_b, g, g.points(), options=MotionOptions(),
                           transport="one-sided")


@pytest.mark.parametrize("name", ["inbetween", "animate_chain"])
@pytest.mark.parametrize("option", ["resolution", "padding_cells", "max_bytes"])
def test_a_pair_or_a_chain_refuses_a_bake_option_it_would_not_read(name, option):
    from keyframe_implicit import core

    grid = unit_grid(3, 9)
    phi = np.zeros(grid.shape)
    call = getattr(core, name)
    with pytest.raises(ValueError, match=f"does not take \\['{option}'\\]"):
        if name == "inbetween":
            call(phi, phi, grid, np.zeros((1, 3)), np.zeros((1, 3)), **{option: 1})
        else:
            call([phi, phi], grid, [(np.zeros((1, 3)), np.zeros((1, 3)))], [1, 2],
                 **{option: 1})
