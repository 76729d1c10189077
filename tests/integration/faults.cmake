# Fault injection (issue 15): kill -9 during writes, SIGINT/SIGTERM during a multi-output command,
# a full and a read-only file system (tmpfs in a private mount namespace), fsync failing (an
# LD_PRELOAD shim), unwritable stdout, oversized inputs (test_cli_faults.py); selfcald under a
# SIGHUP storm, 1000 connections, half-open and trickling clients, SIGTERM under load
# (test_daemon_storm.py).
add_library(fault_fsync SHARED ${CMAKE_CURRENT_SOURCE_DIR}/integration/faults/fault_fsync.c)
# a plain shim: no sanitizer runtime of its own in the preloaded object
target_compile_options(fault_fsync PRIVATE -fno-sanitize=all)
target_link_options(fault_fsync PRIVATE -fno-sanitize=all)
add_test(NAME faults_cli
  COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/faults/test_cli_faults.py
          $<TARGET_FILE:selfcal_cli> $<TARGET_FILE:fault_fsync> ${CMAKE_CURRENT_BINARY_DIR}/tmp/faults_cli 100)
set_tests_properties(faults_cli PROPERTIES TIMEOUT 300 LABELS "integration;faults")
# SIGKILL at each step of an atomic write (strace's syscall injection): no temporary outlives it
add_test(NAME faults_tmp_kill
  COMMAND ${SELFCAL_PYTHON3} ${CMAKE_CURRENT_SOURCE_DIR}/integration/faults/test_tmp_kill.py
          $<TARGET_FILE:selfcal_cli> ${CMAKE_CURRENT_BINARY_DIR}/tmp/faults_tmp_kill)
set_tests_properties(faults_tmp_kill PROPERTIES TIMEOUT 300 LABELS "integration;faults")
if(TARGET selfcald)
  add_test(NAME faults_daemon
    COMMAND ${CMAKE_SOURCE_DIR}/.venv/bin/python ${CMAKE_CURRENT_SOURCE_DIR}/integration/faults/test_daemon_storm.py
            $<TARGET_FILE:selfcal_cli> $<TARGET_FILE:selfcald> ${CMAKE_CURRENT_BINARY_DIR}/tmp/faults_daemon)
  set_tests_properties(faults_daemon PROPERTIES TIMEOUT 300 LABELS "integration;faults;runtime")
endif()
