"""Stage 1: keyframe meshes -> signed distance grids Phi, Psi (thesis sec. 2.1).

``mesh``       vertices checked, faces triangulated and oriented per connected part
``triangles``  exact point-triangle distances (the shell's kernel)
``winding``    generalised winding numbers: inside and outside, robust to holes
``measure``    `read_mesh`: what a keyframe mesh encloses, as the distance field reads it
``sdf``        `mesh_to_sdf`: exact shell, far field, sign (docs/method.md, section 3)
``polygon``    `polygon_to_sdf`: the 2D counterpart
"""
