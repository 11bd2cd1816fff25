"""Stage 4: level sets -> the meshes the artist sees (docs/method.md, section 7).

``extract``     marching cubes / contours, volumes and areas
``template``    one mesh tracked through all frames (shape keys)
``attributes``  the artist's UVs, materials and normals carried onto baked meshes
``quality``     how clean a baked frame is, and which output to store
``meshdata``    the output mesh in Blender's layout (bpy-free)
"""
