# Straightness profiles: dense LAPACK least squares (the tests' reference), fast banded least
# squares with uncertainties, DFT method; time and peak memory for N = 10³..10⁶.
add_executable(bench_profile ${CMAKE_CURRENT_SOURCE_DIR}/bench_profile.c)
target_link_libraries(bench_profile PRIVATE selfcal_static m)
if(NOT TARGET PkgConfig::LAPACKE)
  pkg_check_modules(LAPACKE IMPORTED_TARGET lapacke)
endif()
if(TARGET PkgConfig::LAPACKE)
  target_sources(bench_profile PRIVATE ${CMAKE_SOURCE_DIR}/tests/unit/profile_lsq_dense.c)
  target_include_directories(bench_profile PRIVATE ${CMAKE_SOURCE_DIR}/tests/unit)
  target_compile_definitions(bench_profile PRIVATE SELFCAL_BENCH_DENSE=1)
  target_link_libraries(bench_profile PRIVATE PkgConfig::LAPACKE)
endif()
