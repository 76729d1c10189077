# Documentation that runs (tools/doctest.py; the convention is in docs/testing.md): one test per
# document, README.md and docs/*.md, each running its sh/console/python/c blocks in order in an
# empty folder with the built programs first on PATH, comparing the outputs it shows.
find_program(SELFCAL_PYTHON3 python3)
find_program(SELFCAL_MBPOLL mbpoll)
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli AND TARGET selfcald)
  file(GLOB _docs_md CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/docs/*.md)
  foreach(doc ${PROJECT_SOURCE_DIR}/README.md ${_docs_md})
    get_filename_component(_name ${doc} NAME_WE)
    # python blocks run in the venv that python_package builds (pip install ./python)
    add_test(NAME docs_${_name} COMMAND ${SELFCAL_PYTHON3} ${PROJECT_SOURCE_DIR}/tools/doctest.py
             --bindir $<TARGET_FILE_DIR:selfcal_cli> --python ${CMAKE_CURRENT_BINARY_DIR}/tmp/pyvenv/bin/python
             "--cflags=-I${PROJECT_SOURCE_DIR}/libselfcal/include -I${PROJECT_BINARY_DIR}/include"
             --timeout 900 ${doc} ${CMAKE_CURRENT_BINARY_DIR}/tmp/docs_${_name})
    set_tests_properties(docs_${_name} PROPERTIES TIMEOUT 1000 LABELS "integration;docs")
  endforeach()
  set_tests_properties(docs_README PROPERTIES FIXTURES_REQUIRED selfcal_pyvenv)
  # the guide asks the daemon over Modbus with mbpoll, as the Modbus tests do
  if(NOT SELFCAL_MBPOLL)
    set_tests_properties(docs_guide PROPERTIES DISABLED TRUE)
  endif()
  # the tool's own convention: a broken command, a wrong output, a skip without a reason fail
  add_test(NAME docs_doctest_self COMMAND ${SELFCAL_PYTHON3}
           ${CMAKE_CURRENT_SOURCE_DIR}/integration/docs/doctest_self_test.py
           ${PROJECT_SOURCE_DIR}/tools/doctest.py ${CMAKE_CURRENT_BINARY_DIR}/tmp/docs_self)
  set_tests_properties(docs_doctest_self PROPERTIES TIMEOUT 120 LABELS "integration;docs")
endif()

# every option of `selfcal CMD --help` is in CMD's section of selfcal(1), selfcald --help's in
# selfcald(8), and the reverse
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli AND TARGET selfcald)
  add_test(NAME docs_help_vs_man COMMAND ${SELFCAL_PYTHON3}
           ${CMAKE_CURRENT_SOURCE_DIR}/integration/docs/help_vs_man.py
           $<TARGET_FILE:selfcal_cli> $<TARGET_FILE:selfcald> ${PROJECT_SOURCE_DIR}/docs/man)
  set_tests_properties(docs_help_vs_man PROPERTIES TIMEOUT 120 LABELS "integration;docs;cli")
endif()

# selfcal(1)'s option lists are generated from the commands' option tables (tools/man_options.py)
# and --help names each table's options, both ways
if(SELFCAL_PYTHON3 AND TARGET selfcal_cli)
  add_test(NAME docs_man_options COMMAND ${SELFCAL_PYTHON3}
           ${CMAKE_CURRENT_SOURCE_DIR}/integration/docs/man_options_test.py
           ${PROJECT_SOURCE_DIR}/tools/man_options.py $<TARGET_FILE:selfcal_cli>
           ${PROJECT_SOURCE_DIR}/docs/man/selfcal.1.in ${CMAKE_CURRENT_BINARY_DIR}/tmp/docs_man_options)
  set_tests_properties(docs_man_options PROPERTIES TIMEOUT 300 LABELS "integration;docs;cli")
endif()
