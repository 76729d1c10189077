selfcal_unit_test(NAME test_grid_geometry SOURCES unit/test_grid_geometry.c LIBS selfcal_static LABELS grid)
