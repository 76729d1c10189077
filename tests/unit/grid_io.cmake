# Grid file I/O and the Petrò §5 simulation.
if(TARGET selfcal_grid)
  selfcal_unit_test(NAME test_grid_io SOURCES unit/test_grid_io.c LIBS selfcal_grid LABELS grid TIMEOUT 60)
  selfcal_unit_test(NAME test_grid_sim SOURCES unit/test_grid_sim.c LIBS selfcal_grid LABELS grid TIMEOUT 60)
endif()
