# The plate's scale and temperature (SPEC §11, grid_scale.c): Student's t, the magnification
# gauge's noise against brute force, the scale lines, the model on noise-free data.
selfcal_unit_test(NAME test_grid_scale SOURCES unit/test_grid_scale.c LIBS selfcal_static
                  LABELS grid TIMEOUT 300)
