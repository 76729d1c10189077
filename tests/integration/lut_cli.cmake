# `selfcal lut build|dump|info` through the command line (Python standard library only).
selfcal_cli_script_test(NAME lut_cli SCRIPT integration/lut_cli/test_lut_cli.py
                        TIMEOUT 240 LABELS integration lut)
# `lut info`'s |G| and slope bounds against the table's own dump (docs/linuxcnc.md, "Margins").
selfcal_cli_script_test(NAME lut_bounds SCRIPT integration/lut_cli/test_lut_bounds.py
                        TIMEOUT 120 LABELS integration lut)
