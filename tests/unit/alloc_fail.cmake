# Allocation-failure injection (SQLite's manner): the library's allocations in this test
# executable go through counting wrappers (-Wl,--wrap); every k-th allocation of each call is
# failed in turn and must give SC_E_NOMEM. The library carries no hook.
selfcal_unit_test(NAME test_alloc_fail SOURCES unit/test_alloc_fail.c LIBS selfcal_static LABELS io grid profile TIMEOUT 300)
target_link_options(test_alloc_fail PRIVATE
  -Wl,--wrap=malloc -Wl,--wrap=calloc -Wl,--wrap=realloc -Wl,--wrap=posix_memalign
  -Wl,--wrap=aligned_alloc)
