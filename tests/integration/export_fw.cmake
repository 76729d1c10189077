# Firmware exports (Klipper SET_SKEW, Marlin M852, RepRapFirmware M556) through the command line:
# each firmware's own formula applied to the exported values, residual against the map.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3)
  add_test(NAME export_firmware
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/export_fw/test_firmware.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/export_firmware)
  set_tests_properties(export_firmware PROPERTIES TIMEOUT 120 LABELS "integration;lut;export")
endif()
if(SELFCAL_PYTHON3)
  add_test(NAME export_cli
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/export_fw/test_export_cli.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/export_cli)
  set_tests_properties(export_cli PROPERTIES TIMEOUT 120 LABELS "integration;lut;export")
endif()
