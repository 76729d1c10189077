# selfcald over Modbus with real peers (none written by us): pymodbus (PyPI, pinned in
# tests/requirements.txt, installed into .venv by scripts/install-deps.sh), mbpoll and socat
# (Debian). Each test runs its own daemon on a free port (port 0, read back from its log).
if(TARGET selfcald)
  set(SELFCAL_VENV_PYTHON ${CMAKE_SOURCE_DIR}/.venv/bin/python)
  set(MB_DIR ${CMAKE_CURRENT_SOURCE_DIR}/integration/modbus)
  foreach(t modbus_tcp mbpoll modbus_rtu rtu_bus bounds tcp_defaults traffic daemon_process daemon_audit)
    add_test(NAME it_${t}
      COMMAND ${SELFCAL_VENV_PYTHON} ${MB_DIR}/test_${t}.py $<TARGET_FILE:selfcal_cli>
              $<TARGET_FILE:selfcald> ${CMAKE_CURRENT_BINARY_DIR}/tmp/it_${t})
    set_tests_properties(it_${t} PROPERTIES TIMEOUT 120 LABELS "integration;runtime;modbus")
  endforeach()
  # 3 x 1100 round trips with the line's minimal gaps between the other traffic's frames
  # (about a minute on an idle machine; generous under ASan and ctest -j2)
  set_tests_properties(it_rtu_bus PROPERTIES TIMEOUT 600)
endif()
