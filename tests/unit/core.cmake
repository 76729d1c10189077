# The correction core (selfcal/correct.h): host unit tests. The same test file also runs on an
# emulated Cortex-M4, see tests/cortex-m/cortex-m.cmake.
selfcal_unit_test(NAME test_core SOURCES unit/test_core.c LIBS selfcal_static LABELS core TIMEOUT 60)
# The same tests on the host build of the scalar twin of the SSE2 path (SC_CORR_SCALAR=1): both
# paths must give the same results, and each is tested on its own. The core's two sources are
# compiled into this test, so the library's vector build is not linked.
selfcal_unit_test(NAME test_core_scalar SOURCES unit/test_core.c
  ${CMAKE_SOURCE_DIR}/libselfcal/src/core/correct_apply.c
  ${CMAKE_SOURCE_DIR}/libselfcal/src/core/correct_load.c
  ${CMAKE_SOURCE_DIR}/libselfcal/src/core/correct_explain.c
  LIBS selfcal_static LABELS core TIMEOUT 60)
target_compile_definitions(test_core_scalar PRIVATE SC_CORR_SCALAR=1)

# Cortex-M4F cross build of the core (prints its code and data size) and the same unit tests on
# QEMU mps2-an386 with semihosting. scripts/build-cortex-m.sh does the work.
find_program(SELFCAL_ARM_GCC arm-none-eabi-gcc)
find_program(SELFCAL_QEMU_ARM qemu-system-arm)
if(SELFCAL_ARM_GCC)
  add_test(NAME core_cortex_m4_size
    COMMAND ${CMAKE_SOURCE_DIR}/scripts/build-cortex-m.sh ${CMAKE_BINARY_DIR}/cortex-m)
  set_tests_properties(core_cortex_m4_size PROPERTIES TIMEOUT 120 LABELS "core;cortex-m"
    FIXTURES_SETUP cortex_m4_build)
  if(SELFCAL_QEMU_ARM)
    add_test(NAME core_cortex_m4_qemu
      COMMAND ${CMAKE_SOURCE_DIR}/scripts/build-cortex-m.sh --run-tests ${CMAKE_BINARY_DIR}/cortex-m)
    set_tests_properties(core_cortex_m4_qemu PROPERTIES TIMEOUT 150 LABELS "core;cortex-m"
      FIXTURES_REQUIRED cortex_m4_build)
  endif()
else()
  message(STATUS "arm-none-eabi-gcc not found: the Cortex-M4 build of the core is not tested")
endif()
