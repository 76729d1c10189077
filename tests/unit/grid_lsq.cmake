# Least-squares grid estimator (grid_lsq.c, sparse_sym.c).
selfcal_unit_test(NAME test_grid_lsq SOURCES unit/test_grid_lsq.c LIBS selfcal_static
                  LABELS grid TIMEOUT 300)  # 17 s under load
# dense LAPACK reference for small N
selfcal_unit_test(NAME test_grid_lsq_dense SOURCES unit/test_grid_lsq_dense.c
                  LIBS selfcal_static PkgConfig::LAPACKE LABELS grid TIMEOUT 600)  # 50-62 s under ctest -j2, load 15-25
# the symmetric sparse solver itself (private header of the grid area)
selfcal_unit_test(NAME test_grid_sparse_sym SOURCES unit/test_grid_sparse_sym.c
                  LIBS selfcal_static LABELS grid TIMEOUT 60)
# real measurements (SPEC §5): stitched/rectangular stages, damaged marks, weights, leverage,
# uncertainties, covariance, drift; dense LAPACK references
selfcal_unit_test(NAME test_grid_real SOURCES unit/test_grid_real.c
                  LIBS selfcal_static PkgConfig::LAPACKE LABELS grid TIMEOUT 300)  # 8 s CPU; 57 s wall at load 19
