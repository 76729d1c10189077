# Run-time sized per-view storage: plans, results, 10 002 views through the files, 363 through
# least squares (issue 33).
selfcal_unit_test(NAME test_grid_views SOURCES unit/test_grid_views.c LIBS selfcal_static
                  LABELS grid TIMEOUT 300)  # a few s; 10 000 views under ASan and load
