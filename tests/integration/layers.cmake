# The layers of libselfcal/src that may not be crossed upwards (docs/architecture.md): io/, every
# file format, depends on common/ alone (no include of, and no call into, grid/, profile/, lut/,
# core/ or verify/). The checker first shows that a crossing put into a copy of the tree is found.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3)
  add_test(NAME layers_io COMMAND ${SELFCAL_PYTHON3}
           ${CMAKE_CURRENT_SOURCE_DIR}/integration/layers/check_layers.py --self-test
           ${PROJECT_SOURCE_DIR}/libselfcal/src)
  set_tests_properties(layers_io PROPERTIES TIMEOUT 120 LABELS "integration;io")
endif()
