# Grid file I/O.
selfcal_unit_test(NAME test_grid_io SOURCES unit/test_grid_io.c LIBS selfcal_static LABELS grid TIMEOUT 60)
