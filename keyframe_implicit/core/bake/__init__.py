"""Stage 5: the whole bake, from keyframe meshes to one mesh per timeline frame.

``pipeline``  `animate` and `bake`: plan (checks, grids), distance grids, chain, output
              choice
``keyframe``  `Keyframe`: one keyframe's mesh in world space and its timeline frame
``options``   `BakeOptions`: a bake's options, built once, each stage reading its part
``checks``    refusals before any heavy work, and the result checked after
``gridfit``   the one grid holding every keyframe and feature point, on a lattice in
              world space
``cache``     `WorkCache`: distance grids and maps kept under a key of exactly their
              inputs, in memory and on disk, for a re-bake and the preview to reuse
``memory``    the memory model: a request that would not fit is refused first
``steps``     the bake's counted steps, as its progress names them, and their costs
``maps``      `inbetween`: a pair's two maps solved (threads or helper), then its
              in-betweens
``chain``     `animate_chain`: several keyframes in sequence, paths bent through the
              inner keyframes, segments shared with the helper process
``preview``   `Preview`: the bake's plan on coarse grids (`preview_grids`), its maps
              solved once, then any one frame's surface as the bake makes it (the live
              preview)
"""
