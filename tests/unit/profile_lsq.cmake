# Fast profile least squares (selfcal/profile_lsq.h) against truth, the dense LAPACK reference,
# Monte Carlo and a long-double computation at N = 10⁶.
selfcal_unit_test(NAME test_profile_lsq
  SOURCES unit/test_profile_lsq.c unit/profile_lsq_dense.c
  LIBS selfcal_static PkgConfig::LAPACKE
  LABELS profile threads TIMEOUT 600)  # 46-69 s under ctest -j2, load 15-25
