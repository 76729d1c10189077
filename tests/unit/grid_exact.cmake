# Exact grid methods (Ye, Petrò's double shift): tests against simulated truth.
selfcal_unit_test(NAME test_grid_exact SOURCES unit/test_grid_exact.c
  LIBS selfcal_static LABELS grid TIMEOUT 120)
