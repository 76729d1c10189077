# Straightness profiles (selfcal/profile.h, profile_dft.h, profile_sim.h): both methods against
# simulated truth (random and DABAM profiles), the DFT uncertainty against its brute-force response
# and Monte Carlo, the strict reader.
selfcal_unit_test(NAME test_profile
  SOURCES unit/test_profile.c
  LIBS selfcal_static
  LABELS profile threads TIMEOUT 120)
# glibc fills what malloc hands out with 0x7f bytes (3.5e304 as a double) instead of what freed
# memory held, so that a value read before it is written shows in the results: the DFT plan's
# q = 0 weights, which cancel only when they are finite, are an example (issue 43's mutation
# campaign). The sanitizer build's allocator fills new memory with its own pattern instead.
set_tests_properties(test_profile PROPERTIES ENVIRONMENT "MALLOC_PERTURB_=128")
