# Import of measuring machines' exports: table reader, point numbering (selfcal/import.h).
selfcal_unit_test(NAME test_import SOURCES unit/test_import.c LIBS selfcal_static LABELS "grid;import" TIMEOUT 60)
