# The host table module: SHA-256, table encode/decode, map/profile readers, atomic writing.
selfcal_unit_test(NAME test_lut SOURCES unit/test_lut.c LIBS selfcal_static LABELS lut TIMEOUT 60)
