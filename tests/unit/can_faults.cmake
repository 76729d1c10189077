# Fault injection into the SocketCAN transport: its system calls wrapped by the linker
# (-Wl,--wrap), so that the test can make them fail as a kernel with a CAN stack does (interface
# removed or down, transmit queue full, input frames dropped) without one.
if(SELFCAL_BUILD_RUNTIME)
  selfcal_unit_test(NAME test_can_faults
    SOURCES unit/test_can_faults.c ${PROJECT_SOURCE_DIR}/runtime/transport_can.c
            ${PROJECT_SOURCE_DIR}/runtime/log.c
    LIBS selfcal
    LABELS can runtime faults TIMEOUT 60)
  target_include_directories(test_can_faults PRIVATE ${PROJECT_SOURCE_DIR}/runtime ${SELFCAL_INCLUDE_DIR})
  target_link_options(test_can_faults PRIVATE
    "LINKER:--wrap=socket,--wrap=ioctl,--wrap=setsockopt,--wrap=bind,--wrap=recvmmsg,--wrap=sendmmsg")
endif()
