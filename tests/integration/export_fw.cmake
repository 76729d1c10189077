# Firmware exports (Klipper SET_SKEW, Marlin M852, RepRapFirmware M556) through the command line:
# each firmware's own formula applied to the exported values, residual against the map.
selfcal_cli_script_test(NAME export_firmware SCRIPT integration/export_fw/test_firmware.py
                        TIMEOUT 120 LABELS integration lut export)
selfcal_cli_script_test(NAME export_cli SCRIPT integration/export_fw/test_export_cli.py
                        TIMEOUT 120 LABELS integration lut export)
# The vendors' sign rules applied to exported files: ISG cross compensation of a DABAM-derived
# straightness profile (against selfcald's profile from lut dump), Siemens CEC's "a positive
# value moves the axis negative".
selfcal_cli_script_test(NAME export_cross_signs SCRIPT integration/export_fw/test_cross_signs.py
                        ARGS ${CMAKE_CURRENT_SOURCE_DIR}/data/dabam/dabam-002.dat
                        TIMEOUT 180 LABELS integration lut export)
# The precision-stage controllers (Aerotech Automation1, Power PMAC): the written files read and
# applied by the vendors' documented rules, on the demo's map and a stitched rectangular stage,
# against selfcald's map (lut build + lut dump); the wrong sign doubles the error.
selfcal_cli_script_test(NAME export_precision SCRIPT integration/export_fw/test_precision.py
                        TIMEOUT 300 LABELS integration lut export)
# Straightness profiles as Automation1 1-D axis calibration tables (OUT-1d): read and applied by
# Aerotech's documented rule (linear, nearest end point), against selfcald's profiles, beside the
# demo's map and a stitched stage; the wrong sign doubles the error.
selfcal_cli_script_test(NAME export_a1_profile SCRIPT integration/export_fw/test_a1_profile.py
                        ARGS ${CMAKE_CURRENT_SOURCE_DIR}/data/dabam/dabam-002.dat
                        TIMEOUT 240 LABELS integration lut export)
