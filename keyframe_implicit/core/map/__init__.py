"""Stage 2: the volume map y(x) from keyframe A onto B (thesis ch. 2).

Minimises eq. 2.6, E = w_v E_volume + w_r E_rigidity + w_l E_levelset, subject to the
feature constraints C y = d (eq. 2.14-2.20), by constrained Gauss-Newton, coarse to fine.

``rbf``          the initial map from the feature points (eq. 2.1-2.5)
``terms``        one function per term of eq. 2.6, registered in `terms.TERMS`: a fourth
                 term is one function and one entry there (docs/method.md, section 2)
``constraints``  feature points as affine patches (eq. 2.14-2.20)
``system``       eq. 2.6 discretised on one grid: energy, gradient, Hessian
``hierarchy``    the nested grids and the corrections carried between them
``tear``         where a map spreads one component over several: its pieces and crack
``parts``        components apart in both keyframes: the cells between them leave the solve
``coarse``       the coarse correction of the linear solves
``solver``       `solve_map`: the Gauss-Newton iteration (sec. 2.5)
``result``       `MapResult`, what a solve returns
"""
