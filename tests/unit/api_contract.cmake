# The public headers' promises at their edges: preconditions give error codes, sizes as stated.
selfcal_unit_test(NAME test_api_contract SOURCES unit/test_api_contract.c LIBS selfcal_static
  LABELS api TIMEOUT 60)
