"""Stage 3: the in-between level sets (thesis ch. 3).

``trajectory``  as-rigid-as-possible paths x(s) of every node (sec. 3.1, eq. 3.1)
``finepaths``   paths solved on the motion grid, read at the surface grid's nodes
                (docs/method.md, section 11)
``transport``   a keyframe's field carried along its paths, by inverse lookup (eq. 3.2-3.3)
``band``        the narrow band each frame's transports move and read; signs elsewhere
                (docs/method.md, section 15)
``levelset``    `Inbetween`: the two transports blended (eq. 3.4 read two-sided,
                docs/method.md, section 8)
``isovolume``   the per-frame iso-values that keep the in-between's volume, component by
                component
``components``  the volume each component of an in-between should have
                (docs/method.md, section 13)
``spline``      a chain's paths bent so the velocity flows through its keyframes
                (docs/method.md, section 12)
``tension``     concave folds filled where parts meet (docs/method.md, section 14)
"""
