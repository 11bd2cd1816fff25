"""No deprecated Blender API: the material helper, and the guard every Blender-side test runs in."""

import warnings

import bpy
import pytest

from keyframe_implicit.blender import materials

BLENDER_STYLE = "'Material.use_nodes' is expected to be removed in Blender 6.0"


def test_shader_node_tree_without_deprecated_api(scene):
    mat = bpy.data.materials.new("Skin")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        tree = materials.shader_node_tree(mat)
    assert not [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    assert tree is not None and tree == mat.node_tree
    assert {"BSDF_PRINCIPLED", "OUTPUT_MATERIAL"} <= {n.type for n in tree.nodes}
    if bpy.app.version < materials.NODES_ALWAYS:
        assert mat.use_nodes  # on 4.x the switch is what makes the tree render


def test_helper_stops_using_use_nodes_where_blender_deprecates_it(scene, kfi):
    mat = bpy.data.materials.new("Skin")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mat.use_nodes  # noqa: B018 - reading it is what may warn
    flagged = kfi.blender_deprecations(caught)
    assert bool(flagged) == (bpy.app.version >= materials.NODES_ALWAYS), [str(w.message) for w in caught]


def test_guard_picks_blender_deprecations_of_this_checkout_only(kfi):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warnings.warn(BLENDER_STYLE, DeprecationWarning)                      # ours: flagged
        warnings.warn_explicit(BLENDER_STYLE, DeprecationWarning,             # another package's
                               "/elsewhere/site-packages/other_addon.py", 7)
        warnings.warn("Setting the shape on a NumPy array has been deprecated in NumPy 2.5.",
                      DeprecationWarning)                                     # not Blender's API
        warnings.warn(BLENDER_STYLE, UserWarning)                             # not a deprecation
    flagged = kfi.blender_deprecations(caught)
    assert [(w.category, w.filename) for w in flagged] == [(DeprecationWarning, __file__)]


def test_guard_fails_the_test_and_passes_other_warnings_on(kfi):
    with pytest.raises(pytest.fail.Exception, match="Material.use_nodes"):
        with kfi.failing_on_blender_deprecations():
            warnings.warn(BLENDER_STYLE, DeprecationWarning)
    with pytest.warns(DeprecationWarning, match="NumPy 2.5"):
        with kfi.failing_on_blender_deprecations():
            warnings.warn("Setting the shape on a NumPy array has been deprecated in NumPy 2.5.",
                          DeprecationWarning)
