"""Checks run before baking and shown in the sidebar.

`problems` returns every issue of a scene setup as `Problem` objects whose
message says what is wrong AND what to do. ERROR problems block the bake;
WARNING problems are hints (e.g. fewer than 4 feature pairs is allowed by the
core but gives the solver a poor start).
"""

from dataclasses import dataclass

from . import features

ERROR = "ERROR"
WARNING = "WARNING"

MIN_PAIRS_HINT = 4


@dataclass(frozen=True)
class Problem:
    level: str  # ERROR or WARNING
    message: str
    segment: int = -1  # the segment it concerns, -1 for the whole setup

    @property
    def icon(self):
        return "ERROR" if self.level == ERROR else "INFO"


def problems(scene, settings=None):
    """All problems of ``scene``'s keyframe_implicit setup, errors first."""
    if settings is None:
        settings = scene.keyframe_implicit
    out = []
    kfs = list(settings.keyframes)
    if len(kfs) < 2:
        out.append(Problem(ERROR, f"{len(kfs)} keyframe(s): add at least two (select a mesh, "
                                  "set the frame, press Add Keyframe)."))
    for i, kf in enumerate(kfs):
        if kf.object is None:
            out.append(Problem(ERROR, f"Keyframe {i} (frame {kf.frame}) has no object: pick a mesh "
                                      "object or remove the keyframe."))
        elif kf.object.type != "MESH":
            out.append(Problem(ERROR, f"Keyframe {i}: '{kf.object.name}' is not a mesh: pick a mesh "
                                      "object (convert curves/text with Object > Convert > Mesh)."))
        elif kf.object.name not in scene.objects:
            out.append(Problem(ERROR, f"Keyframe {i}: '{kf.object.name}' is not in this scene: link "
                                      "it into the scene or pick another object."))
        elif len(kf.object.data.polygons) == 0:
            out.append(Problem(ERROR, f"Keyframe {i}: '{kf.object.name}' has no faces: a keyframe "
                                      "must be a closed surface."))
    frames = [kf.frame for kf in kfs]
    seen = {}
    for i, f in enumerate(frames):
        if f in seen:
            out.append(Problem(ERROR, f"Keyframes {seen[f]} and {i} are both on frame {f}: give "
                                      "each keyframe its own frame."))
        seen.setdefault(f, i)
    for i in range(1, len(frames)):
        if frames[i] < frames[i - 1]:
            out.append(Problem(ERROR, f"Keyframe {i} (frame {frames[i]}) comes after keyframe "
                                      f"{i - 1} (frame {frames[i - 1]}) in the list: order the list "
                                      "by frame (Move Up/Down) or change the frames."))
    n_seg = max(len(kfs) - 1, 0)
    counts = [0] * n_seg
    for pair in features.pairs(scene).values():
        name = (pair.a or pair.b).name
        if not 0 <= pair.segment < n_seg:
            out.append(Problem(ERROR, f"Feature '{name}' belongs to segment {pair.segment}, which "
                                      f"does not exist ({len(kfs)} keyframes): remove the pair."))
            continue
        if not pair.complete:
            out.append(Problem(ERROR, f"Feature '{name}' has no partner: delete it, or select it "
                                      "with another Empty and press Pair Selected.", pair.segment))
            continue
        kf_a = kfs[pair.segment].object
        kf_b = kfs[pair.segment + 1].object
        bad = [(s, e, kf) for s, e, kf in (("A", pair.a, kf_a), ("B", pair.b, kf_b))
               if kf is not None and e.parent != kf]
        for side, e, kf in bad:
            out.append(Problem(WARNING, f"'{e.name}' is not parented to keyframe "
                                        f"{pair.segment + (side == 'B')} ('{kf.name}'): it will not "
                                        "follow that object; parent it (Ctrl+P > Keep Transform).",
                               pair.segment))
        counts[pair.segment] += 1
    for seg, n in enumerate(counts):
        if n < MIN_PAIRS_HINT:
            out.append(Problem(WARNING, f"Segment {seg} (keyframe {seg} -> {seg + 1}) has {n} "
                                        f"feature pair(s); {MIN_PAIRS_HINT} or more on distinctive "
                                        "points give a better correspondence (Add Feature Pair).", seg))
    out.sort(key=lambda p: p.level != ERROR)
    return out


def errors(found):
    return [p for p in found if p.level == ERROR]


def raise_on_errors(scene, settings=None):
    """Raise ValueError listing every blocking problem (what is wrong and what to do)."""
    errs = errors(problems(scene, settings))
    if errs:
        raise ValueError("Cannot bake: " + " ".join(p.message for p in errs))
