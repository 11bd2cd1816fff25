"""The bake's counted steps, in the words the artist reads in its progress (`progress.Tally`,
`pipeline.bake_steps`): a distance field per keyframe, a map per direction of each pair of
keyframes, a path step per segment (its trajectories, and one more for every segment's
bends through the keyframes) and a timeline frame.
"""

__all__ = ["DISTANCE_FIELDS", "MAPS", "PATHS", "FRAMES", "MAP_CELL_COST", "PATH_CELL_COST"]

DISTANCE_FIELDS, MAPS, PATHS, FRAMES = "Distance fields", "Maps", "Paths", "Frames"

#: What a step costs per cell of its grid, in a distance field's cell: a map's (the
#: Gauss-Newton solve, coarse to fine) and a path's (a segment's trajectories, or every
#: segment's bends through the keyframes). Timed on the merge and splash examples at
#: resolution 48: a map's cell took 7-10 times a distance field's, a path's 2-5 times, a
#: frame's about once.
MAP_CELL_COST = 8.0
PATH_CELL_COST = 3.0
