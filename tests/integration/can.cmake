# SocketCAN tests of selfcald on a real vcan interface, driven by can-utils (cansend, candump,
# cangen) and the can_traffic generator; the frames are checked with cantools against
# runtime/selfcald.dbc. Where the host cannot create a vcan interface (these machines' kernel has no
# CAN), tests/integration/vcan/run-vcan.sh boots Debian's kernel under QEMU with the CAN modules
# (scripts/fetch-test-kernel.sh). Never skipped: a missing QEMU, kernel or tool fails the test.
# The guest runs the binaries of this build (ASan/UBSan ones included: run-vcan copies every library
# ldd lists, and gives the guest 768 MB).
set(SELFCAL_VCAN_DIR ${CMAKE_CURRENT_SOURCE_DIR}/integration/vcan)
set(SELFCAL_VENV_PYTHON ${CMAKE_SOURCE_DIR}/.venv/bin/python)
set(SELFCAL_TEST_KERNEL_DIR ${CMAKE_SOURCE_DIR}/.cache/kernel CACHE PATH
    "Unpacked Debian kernel package for the vcan tests (scripts/fetch-test-kernel.sh)")

if(NOT TARGET can_traffic)
  add_executable(can_traffic ${SELFCAL_VCAN_DIR}/can_traffic.c)
  set_target_properties(can_traffic PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin)
endif()

# The harness alone: cansend -> candump round trip (no selfcald).
add_test(NAME vcan_roundtrip
  COMMAND ${SELFCAL_VCAN_DIR}/run-vcan.sh --script ${SELFCAL_VCAN_DIR}/roundtrip-test.sh
          --work ${CMAKE_CURRENT_BINARY_DIR}/tmp/vcan_roundtrip --timeout 350)
# Time limits: at least 5x the durations under `ctest -j2` on a loaded 2-core machine
# (roundtrip 46 s, selfcald 69 s, traffic_short 76 s with the load average at 22-25).
set_tests_properties(vcan_roundtrip PROPERTIES TIMEOUT 400 LABELS "integration;runtime;can"
  ENVIRONMENT "SELFCAL_KERNEL_DIR=${SELFCAL_TEST_KERNEL_DIR}")

if(TARGET selfcald AND TARGET selfcal_cli)
  set(_vcan_args --cli $<TARGET_FILE:selfcal_cli> --selfcald $<TARGET_FILE:selfcald>
      --traffic $<TARGET_FILE:can_traffic> --dbc ${CMAKE_SOURCE_DIR}/runtime/selfcald.dbc)
  # cansend/candump/cangen against an independent evaluation of the table, bad frames, the
  # 1 Hz status frame, noise, raster and circle traffic, bus-off, interface down and removed.
  add_test(NAME vcan_selfcald
    COMMAND ${SELFCAL_VENV_PYTHON} ${SELFCAL_VCAN_DIR}/vcan_test.py ${_vcan_args}
            --work ${CMAKE_CURRENT_BINARY_DIR}/tmp/vcan_selfcald --rate 2000 --timeout 550)
  # The benchmark's path, short and without a speed target (bench/can.cmake has the real one).
  add_test(NAME vcan_traffic_short
    COMMAND ${SELFCAL_VENV_PYTHON} ${SELFCAL_VCAN_DIR}/vcan_test.py ${_vcan_args} --bench
            --work ${CMAKE_CURRENT_BINARY_DIR}/tmp/vcan_traffic_short --rate 4000 --seconds 2
            --timeout 550)
  set_tests_properties(vcan_selfcald vcan_traffic_short PROPERTIES TIMEOUT 600
    LABELS "integration;runtime;can" ENVIRONMENT "SELFCAL_KERNEL_DIR=${SELFCAL_TEST_KERNEL_DIR}")
else()
  # Never skip: without the daemon the CAN tests fail and say why.
  add_test(NAME vcan_selfcald COMMAND sh -c "echo 'vcan_selfcald: selfcald or selfcal_cli is not built (see runtime/CMakeLists.txt)'; exit 1")
  set_tests_properties(vcan_selfcald PROPERTIES LABELS "integration;runtime;can")
endif()
