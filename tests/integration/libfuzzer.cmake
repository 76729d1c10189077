# libFuzzer targets (issue 15): with -DSELFCAL_FUZZ=ON and clang, one fuzz_<target> per input the
# project parses, linked with ASan+UBSan. Sources, seed corpora (tests/fuzz/<target>/corpus),
# dictionaries (tests/fuzz/<target>/dict) and regression inputs of fixed findings
# (tests/fuzz/<target>/regressions) are in tests/fuzz. Each gets a short CTest run
# (fuzz_short_<target>, label fuzz-short, SELFCAL_FUZZ_SECONDS each, default 20) that starts from
# the seeds and the regressions and writes new inputs into the build tree only; scripts/fuzz.sh
# runs long campaigns.
if(SELFCAL_FUZZ)
  set(SELFCAL_FUZZ_SECONDS 20 CACHE STRING "Seconds each fuzz_short_<target> test runs")
  set(_fz ${CMAKE_CURRENT_SOURCE_DIR}/fuzz)
  set(_fz_targets grid_read profile_read stage_map profile_result table selfcald_config
                  modbus_adu modbus_rtu can_frame import import_layout plate_map dabam verify plot_xy)
  foreach(t ${_fz_targets})
    add_executable(fuzz_${t} ${_fz}/fuzz_${t}.c)
    target_include_directories(fuzz_${t} PRIVATE ${_fz})
    target_compile_definitions(fuzz_${t} PRIVATE _GNU_SOURCE)
    target_compile_options(fuzz_${t} PRIVATE -fsanitize=fuzzer)
    target_link_options(fuzz_${t} PRIVATE -fsanitize=fuzzer)
    if(t MATCHES "^(selfcald_config|modbus_adu|modbus_rtu|can_frame)$")
      target_link_libraries(fuzz_${t} PRIVATE selfcald_lib m)
    else()
      target_link_libraries(fuzz_${t} PRIVATE selfcal_static m)
    endif()
    # `plot xy`'s reader lives in the CLI's sources
    if(t STREQUAL "plot_xy")
      target_sources(fuzz_${t} PRIVATE ${PROJECT_SOURCE_DIR}/tools/selfcal/cmd_plot_xy.c
                                       ${PROJECT_SOURCE_DIR}/tools/selfcal/cli_opts.c
                                       ${PROJECT_SOURCE_DIR}/tools/selfcal/svg.c)
    endif()
    if(t STREQUAL "plot_xy")
      target_include_directories(fuzz_${t} PRIVATE ${PROJECT_SOURCE_DIR}/tools/selfcal)
    endif()
    set_target_properties(fuzz_${t} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/fuzz)
    set(_work ${CMAKE_CURRENT_BINARY_DIR}/tmp/fuzz-corpus/${t})
    file(MAKE_DIRECTORY ${_work})
    set(_dirs ${_work} ${_fz}/${t}/corpus)
    if(EXISTS ${_fz}/${t}/regressions)
      list(APPEND _dirs ${_fz}/${t}/regressions)
    endif()
    set(_dict)
    if(EXISTS ${_fz}/${t}/dict)
      set(_dict -dict=${_fz}/${t}/dict)
    endif()
    add_test(NAME fuzz_short_${t}
      COMMAND fuzz_${t} -max_total_time=${SELFCAL_FUZZ_SECONDS} -timeout=10 -rss_limit_mb=2048
              -max_len=65536 -print_final_stats=1 ${_dict} ${_dirs})
    math(EXPR _limit "${SELFCAL_FUZZ_SECONDS} * 5 + 30")
    set_tests_properties(fuzz_short_${t} PROPERTIES TIMEOUT ${_limit} LABELS "fuzz-short;fuzz")
  endforeach()
endif()
