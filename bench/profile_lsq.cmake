# bench_profile_lsq: dense LAPACK least squares vs the fast banded one (time, peak memory).
if(NOT TARGET PkgConfig::LAPACKE)
  pkg_check_modules(LAPACKE IMPORTED_TARGET lapacke)  # the tests require it; a bench-only build may lack it
endif()
if(TARGET PkgConfig::LAPACKE)
  add_executable(bench_profile_lsq
    ${CMAKE_CURRENT_SOURCE_DIR}/bench_profile_lsq.c
    ${PROJECT_SOURCE_DIR}/tests/unit/profile_lsq_dense.c)
  target_include_directories(bench_profile_lsq PRIVATE ${PROJECT_SOURCE_DIR}/tests/unit)
  target_link_libraries(bench_profile_lsq PRIVATE selfcal_static PkgConfig::LAPACKE m)
else()
  message(STATUS "lapacke not found: bench_profile_lsq (dense reference) is not built")
endif()
