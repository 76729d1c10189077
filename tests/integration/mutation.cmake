# Mutation testing (issue 43): a fixed small sample of mutants (tests/mutation/ci_sample.txt: the
# three bugs no test caught, the leverage, the offsets' sign, and some of every module), each of
# which must fail the tests tests/mutation/modules.txt names for its file. scripts/mutate.sh builds
# a Release copy of the sources under this build tree (ccache) and never touches the checkout.
# About a minute with a warm ccache; a failure names the surviving mutant.
find_program(SELFCAL_NINJA ninja)
if(SELFCAL_NINJA AND TARGET selfcald AND TARGET selfcal_cli)
  add_test(NAME mutation_sample
    COMMAND ${CMAKE_SOURCE_DIR}/scripts/mutate.sh --sample-file
            ${CMAKE_SOURCE_DIR}/tests/mutation/ci_sample.txt --fail-on-survivor
            --work ${CMAKE_CURRENT_BINARY_DIR}/mutation)
  set_tests_properties(mutation_sample PROPERTIES TIMEOUT 900 LABELS "mutation"
    ENVIRONMENT "NICE=10")
endif()
