# Real rigs (SPEC §2a): gaps, probe gain and angle scale, drift, residuals and outliers, the χ²
# verdict and the coverage of u(f) over 200 simulated runs.
selfcal_unit_test(NAME test_profile_rig
  SOURCES unit/test_profile_rig.c
  LIBS selfcal_static
  LABELS profile TIMEOUT 120)
