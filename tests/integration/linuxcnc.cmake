# The LinuxCNC HAL component under LinuxCNC's halrun (POSIX non-realtime), against an independent
# evaluation of `selfcal lut dump` and against selfcald (when built). One HAL session at a time on
# a machine (shared memory, one rtapi_app): RESOURCE_LOCK linuxcnc_hal for every such test.
if(SELFCAL_HAL_MODULE)
  set(_py ${CMAKE_SOURCE_DIR}/.venv/bin/python)
  set(_daemon "")
  if(TARGET selfcald)
    set(_daemon $<TARGET_FILE:selfcald>)
  endif()
  add_test(NAME linuxcnc_hal
    COMMAND ${_py} ${CMAKE_CURRENT_SOURCE_DIR}/integration/linuxcnc/test_hal.py
            $<TARGET_FILE:selfcal_cli> ${SELFCAL_HAL_MODULE} ${CMAKE_CURRENT_BINARY_DIR}/tmp/linuxcnc_hal
            ${_daemon})
  set_tests_properties(linuxcnc_hal PROPERTIES TIMEOUT 300 SKIP_RETURN_CODE 77
                       RESOURCE_LOCK linuxcnc_hal LABELS "integration;linuxcnc")
  # enable, ramp-ms, max-correction (SPEC §7a) and the exact inverse of the command chain
  add_test(NAME linuxcnc_hal_ramp
    COMMAND ${_py} ${CMAKE_CURRENT_SOURCE_DIR}/integration/linuxcnc/test_hal_ramp.py
            $<TARGET_FILE:selfcal_cli> ${SELFCAL_HAL_MODULE} ${CMAKE_CURRENT_BINARY_DIR}/tmp/linuxcnc_hal_ramp)
  set_tests_properties(linuxcnc_hal_ramp PROPERTIES TIMEOUT 300 SKIP_RETURN_CODE 77
                       RESOURCE_LOCK linuxcnc_hal LABELS "integration;linuxcnc")
  # the example machine examples/linuxcnc under LinuxCNC itself (milltask, motion, homing)
  add_test(NAME linuxcnc_machine
    COMMAND ${_py} ${CMAKE_CURRENT_SOURCE_DIR}/integration/linuxcnc/test_machine.py
            $<TARGET_FILE:selfcal_cli> ${SELFCAL_HAL_MODULE} ${CMAKE_CURRENT_BINARY_DIR}/tmp/linuxcnc_machine)
  set_tests_properties(linuxcnc_machine PROPERTIES TIMEOUT 600 SKIP_RETURN_CODE 77
                       RESOURCE_LOCK linuxcnc_hal LABELS "integration;linuxcnc")
endif()
