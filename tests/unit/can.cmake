# Unit tests of the SocketCAN transport of selfcald (no CAN stack needed: a socketpair plays the bus).
# The transport source is compiled in directly, with a fake engine in the test, so the test does not
# depend on the rest of the daemon (only on the library's sc_error, the runtime's error convention).
if(SELFCAL_BUILD_RUNTIME)
  selfcal_unit_test(NAME test_can
    SOURCES unit/test_can.c ${PROJECT_SOURCE_DIR}/runtime/transport_can.c
            ${PROJECT_SOURCE_DIR}/runtime/log.c
    LIBS selfcal
    LABELS can runtime TIMEOUT 60)
  target_include_directories(test_can PRIVATE ${PROJECT_SOURCE_DIR}/runtime ${SELFCAL_INCLUDE_DIR})
endif()
