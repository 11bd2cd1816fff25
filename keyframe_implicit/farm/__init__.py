"""The bake on a render farm: its stages as separate tasks over a job directory.

``stages``    the bake taken apart where its work is independent: prepare, pairs' maps,
              the paths, a segment's frames, assemble (bpy-free)
``store``     the job directory's files: plain arrays and a JSON tree, a manifest
``job_template``  the Open Job Description job template that runs the stages in order
``flamenco``  the same job as a Flamenco job type (JavaScript)

The Blender side of prepare and assemble, and the panel's Export Farm Job, are in
``blender.farm``, which imports this package; the command line that runs each stage,
``python -m keyframe_implicit farm STAGE ...``, is ``cli.farm``. Nothing here imports
either: this package sits below the Blender side and the command line, beside the
worker, whose ``python_path`` the job template reads.
"""
