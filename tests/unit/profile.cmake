# Straightness profiles (selfcal/profile.h, profile_dft.h, profile_sim.h): both methods against
# simulated truth (random and DABAM profiles), the DFT uncertainty against its brute-force response
# and Monte Carlo, the strict reader.
selfcal_unit_test(NAME test_profile
  SOURCES unit/test_profile.c
  LIBS selfcal_static
  LABELS profile threads TIMEOUT 120)
