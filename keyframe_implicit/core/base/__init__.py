"""What every stage stands on: the grid and the numerics shared across the method.

``grid``       `Grid`, the regular grid every field and map lives on (thesis sec. 2.1)
``sampling``   multilinear and cubic reads of grid fields at off-grid points; the smooth ramp
``elements``   multilinear finite elements on the cells (F = dy/dx, eq. 2.9-2.10) and
               the closed-form algebra of their small matrices
``rotations``  polar decomposition, rotation log/exp, rigid fits (appendix A)
``multigrid``  the block multigrid preconditioner of the Poisson solves
``progress``   progress reports and cancellation
``parallel``   the helper process, BLAS threads, memory given back
``wire``       the messages between the bake's processes, and a child following its parent
"""
