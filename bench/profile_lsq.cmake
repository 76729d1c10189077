# bench_profile_lsq: dense LAPACK least squares vs the fast banded one (time, peak memory).
if(NOT TARGET PkgConfig::LAPACKE)
  pkg_check_modules(LAPACKE IMPORTED_TARGET lapacke)  # the tests find it; a bench-only build too
endif()
if(TARGET selfcal_profile AND TARGET PkgConfig::LAPACKE)
  add_executable(bench_profile_lsq
    ${CMAKE_CURRENT_SOURCE_DIR}/bench_profile_lsq.c
    ${PROJECT_SOURCE_DIR}/tests/unit/profile_lsq_dense.c)
  target_include_directories(bench_profile_lsq PRIVATE ${PROJECT_SOURCE_DIR}/tests/unit)
  target_link_libraries(bench_profile_lsq PRIVATE selfcal_profile PkgConfig::LAPACKE m)
endif()
