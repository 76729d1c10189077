# The controller exporters: every written table is parsed back and interpolated independently.
selfcal_unit_test(NAME test_export SOURCES unit/test_export.c LIBS selfcal_static LABELS lut TIMEOUT 60)
