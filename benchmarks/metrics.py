"""Quality metrics of an in-between sequence (vectorised numpy / scipy / scikit-image).

All lengths are reported in grid spacings h. A "sequence" is a list of level
set grids at times ``s`` (negative inside), keyframe A at s = 0 and B at s = 1.

- `volume`: volume inside the surface the artist gets (marching cubes of the
  frame's field, `keyframe_implicit.core.surface.extract.enclosed_volume`), the same for
  every method whether its field is a distance or not.
- `volume_drift`: max over s of |V(s) - V_lin(s)| / V_lin(s), V_lin the linear
  interpolation of the keyframe volumes.
- `components`: connected pieces of {phi < 0} (6-connected voxels).
- `spurious_components`: max over frames of components - max(components of the
  two keyframes), floored at 0; a frame with no material counts as spurious too.
- `surface_error`: |reference signed distance| at the vertices of the method's
  zero set (marching cubes), mean and max, in h.
- `feature_error`: |map(x'_i) - y'_i| in h, map sampled multilinearly.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from skimage import measure

from keyframe_implicit.core.base.sampling import sample
from keyframe_implicit.core.surface.extract import enclosed_volume

__all__ = [
    "volume", "volume_drift", "components", "spurious_components", "zero_set",
    "surface_error", "feature_error", "active_voxels",
]


def volume(phi, grid):
    """Volume inside the zero set of ``phi`` (marching cubes), world units^3."""
    return enclosed_volume(np.asarray(phi, dtype=float), grid)


def volume_drift(volumes, times, keyframe_volumes=None):
    """max over frames of |V(s) - V_lin(s)| / V_lin(s) (fraction, not percent).

    ``volumes`` and ``times`` list every frame. V_lin(s) = (1 - s) V_A + s V_B
    with (V_A, V_B) = ``keyframe_volumes``, the volumes of the keyframes
    themselves (so a method whose end frame misses B is charged for it);
    without it, the first and last frames' volumes.
    """
    v = np.asarray(volumes, dtype=float)
    s = np.asarray(times, dtype=float)
    va, vb = (v[0], v[-1]) if keyframe_volumes is None else keyframe_volumes
    lin = (1 - s) * va + s * vb
    return float(np.max(np.abs(v - lin) / lin))


def components(phi):
    """Number of 6-connected components of {phi < 0}."""
    _, n = ndimage.label(np.asarray(phi) < 0)
    return int(n)


def spurious_components(counts, expected_a, expected_b):
    """max over frames of (count - max(expected_a, expected_b)), floored at 0.

    A frame whose material vanished (count 0) counts as max(expected) spurious
    pieces lost, so a sequence that empties out does not look clean.
    """
    c = np.asarray(counts)
    ref = max(expected_a, expected_b)
    extra = np.maximum(c - ref, 0)
    lost = np.where(c == 0, ref, 0)
    return int(np.max(np.maximum(extra, lost)))


def zero_set(phi, grid):
    """Marching-cubes vertices (V, 3) of phi = 0 in world units; (0, 3) if none."""
    phi = np.asarray(phi, dtype=float)
    if not (phi.min() < 0 < phi.max()):
        return np.zeros((0, 3))
    verts, _, _, _ = measure.marching_cubes(phi, 0.0, spacing=(grid.spacing,) * 3)
    return verts + grid.origin


def surface_error(phi, grid, reference):
    """Mean and max |reference(v)| / h over the zero-set vertices v of ``phi``.

    ``reference`` is a callable (P, 3) -> signed distance (e.g. the analytic
    ground truth) or a grid array (sampled multilinearly, distance outside).
    Returns (nan, nan) when phi has no zero set.
    """
    v = zero_set(phi, grid)
    if len(v) == 0:
        return float("nan"), float("nan")
    if callable(reference):
        d = np.abs(reference(v))
    else:
        d = np.abs(sample(reference, grid, v, outside="distance"))
    return float(d.mean() / grid.spacing), float(d.max() / grid.spacing)


def feature_error(mapped, grid, features_a, features_b):
    """|y(x'_i) - y'_i| / h for each feature pair, y the node map ``mapped`` (grid.shape + (3,))."""
    y = sample(np.asarray(mapped, dtype=float), grid, np.asarray(features_a, dtype=float))
    return np.linalg.norm(y - np.asarray(features_b, dtype=float), axis=-1) / grid.spacing


def active_voxels(phi, grid, band=2.0):
    """Nodes with phi < band * h (material of A plus a band), the cost-growth abscissa."""
    return int(np.count_nonzero(np.asarray(phi) < band * grid.spacing))
