# The grid simulation (Petrò §5).
selfcal_unit_test(NAME test_grid_sim SOURCES unit/test_grid_sim.c LIBS selfcal_static LABELS grid TIMEOUT 60)
