# Seeded mutation fuzzing of every input the product reads besides the grid input file (that one
# is fuzzed by grid_cli_test.py): profile inputs, maps, profile results, tables, selfcald's
# configuration, command line, tables and Modbus TCP. Python 3 standard library only. Each test
# runs a modest, fixed number of cases (same seed every run), sized so that it takes at most a fifth
# of its time limit under `ctest -j2` on a loaded 2-core machine (with the load average at 22-25:
# 3.6-6 cases/s, so 120-200 cases take 25-35 s; fuzz_selfcald_config 23 s); longer campaigns:
#   python3 tests/integration/fuzz/fuzz_cli.py build/bin/selfcal profile --iterations 5000 --seed 7
# The extreme magnitudes that once crashed the exporters and gave inf/NaN outputs (fuzzlib.py,
# KNOWN_EXTREME) are part of every run: the readers now refuse them with file:line.
find_program(SELFCAL_PYTHON3 python3)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  set(_fuzz_dir ${CMAKE_CURRENT_SOURCE_DIR}/integration/fuzz)
  set(_fuzz_tmp ${CMAKE_CURRENT_BINARY_DIR}/tmp/fuzz)
  foreach(spec "profile;200" "lut-build;120" "lut-table;120" "export;150" "plot;150")
    list(GET spec 0 target)
    list(GET spec 1 iters)
    add_test(NAME fuzz_cli_${target}
      COMMAND ${SELFCAL_PYTHON3} ${_fuzz_dir}/fuzz_cli.py $<TARGET_FILE:selfcal_cli> ${target}
              --iterations ${iters} --work ${_fuzz_tmp})
    set_tests_properties(fuzz_cli_${target} PROPERTIES TIMEOUT 300 LABELS "integration;fuzz")
  endforeach()
  if(TARGET selfcald)
    foreach(spec "config;150" "argv;150" "table;60" "modbus;150")
      list(GET spec 0 target)
      list(GET spec 1 iters)
      add_test(NAME fuzz_selfcald_${target}
        COMMAND ${SELFCAL_PYTHON3} ${_fuzz_dir}/fuzz_selfcald.py $<TARGET_FILE:selfcal_cli>
                $<TARGET_FILE:selfcald> ${target} --iterations ${iters} --work ${_fuzz_tmp})
      set_tests_properties(fuzz_selfcald_${target} PROPERTIES TIMEOUT 300 LABELS "integration;fuzz")
    endforeach()
  endif()
endif()
