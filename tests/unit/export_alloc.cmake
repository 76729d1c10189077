# Allocation-failure injection into every exporter: the library's malloc/calloc/realloc in this
# executable go through counting wrappers (-Wl,--wrap), every k-th allocation of each export is
# failed in turn and must give SC_E_NOMEM.
selfcal_unit_test(NAME test_export_alloc SOURCES unit/test_export_alloc.c LIBS selfcal_static LABELS lut faults TIMEOUT 60)
target_link_options(test_export_alloc PRIVATE -Wl,--wrap=malloc -Wl,--wrap=calloc -Wl,--wrap=realloc)
