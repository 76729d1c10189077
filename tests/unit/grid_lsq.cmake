# Least-squares grid estimator (grid/grid_lsq_*.c, linalg/sparse_sym*.c); the reference solves of
# its accuracy tests are a test helper (unit/grid_lsq_reference.c).
selfcal_unit_test(NAME test_grid_lsq SOURCES unit/test_grid_lsq.c unit/grid_lsq_reference.c
                  LIBS selfcal_static
                  LABELS grid TIMEOUT 300)  # 17 s under load
# dense LAPACK reference for small N
selfcal_unit_test(NAME test_grid_lsq_dense SOURCES unit/test_grid_lsq_dense.c
                  LIBS selfcal_static PkgConfig::LAPACKE LABELS grid TIMEOUT 600)  # 50-62 s under ctest -j2, load 15-25
# the symmetric sparse solver itself (linalg/sparse_sym.h, private to the library)
selfcal_unit_test(NAME test_grid_sparse_sym SOURCES unit/test_grid_sparse_sym.c
                  LIBS selfcal_static LABELS grid TIMEOUT 60)
# real measurements (SPEC §5): stitched/rectangular stages, damaged marks, weights, leverage,
# uncertainties, covariance, drift; dense LAPACK references
selfcal_unit_test(NAME test_grid_real SOURCES unit/test_grid_real.c
                  LIBS selfcal_static PkgConfig::LAPACKE LABELS grid TIMEOUT 600)  # 30-60 s alone, 120+ s at load 17 under ctest -j2
# A kept as unknowns (issue 33): the same results as the reduced solver, the automatic choice,
# the sampled node σ
selfcal_unit_test(NAME test_grid_lsq_full SOURCES unit/test_grid_lsq_full.c unit/grid_lsq_reference.c
                  LIBS selfcal_static
                  LABELS grid TIMEOUT 300)
# a 401 x 401 stage from a 41-mark plate in 363 placements, noise-free (issue 33): A kept, G to
# 1e-6 um, sampled σ against refined solves
selfcal_unit_test(NAME test_grid_lsq_large SOURCES unit/test_grid_lsq_large.c unit/grid_lsq_reference.c
                  LIBS selfcal_static
                  LABELS grid large TIMEOUT 1800)
