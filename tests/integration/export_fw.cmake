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
# The vendors' sign rules applied to exported files: ISG cross compensation of a DABAM-derived
# straightness profile (against selfcald's profile from lut dump), Siemens CEC's "a positive
# value moves the axis negative".
if(SELFCAL_PYTHON3)
  add_test(NAME export_cross_signs
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/export_fw/test_cross_signs.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/export_cross_signs
            ${CMAKE_CURRENT_SOURCE_DIR}/data/dabam/dabam-002.dat)
  set_tests_properties(export_cross_signs PROPERTIES TIMEOUT 180 LABELS "integration;lut;export")
endif()
# The precision-stage controllers (Aerotech Automation1, Power PMAC): the written files read and
# applied by the vendors' documented rules, on the demo's map and a stitched rectangular stage,
# against selfcald's map (lut build + lut dump); the wrong sign doubles the error.
if(SELFCAL_PYTHON3)
  add_test(NAME export_precision
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/export_fw/test_precision.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/export_precision)
  set_tests_properties(export_precision PROPERTIES TIMEOUT 300 LABELS "integration;lut;export")
endif()
# Straightness profiles as Automation1 1-D axis calibration tables (OUT-1d): read and applied by
# Aerotech's documented rule (linear, nearest end point), against selfcald's profiles, beside the
# demo's map and a stitched stage; the wrong sign doubles the error.
if(SELFCAL_PYTHON3)
  add_test(NAME export_a1_profile
    COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/export_fw/test_a1_profile.py
            $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/export_a1_profile
            ${CMAKE_CURRENT_SOURCE_DIR}/data/dabam/dabam-002.dat)
  set_tests_properties(export_a1_profile PROPERTIES TIMEOUT 240 LABELS "integration;lut;export")
endif()
