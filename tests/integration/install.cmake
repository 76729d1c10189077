# The installed product (SPEC §6): install into a temporary prefix and build + run examples/ both
# ways against it (pkg-config Makefile, find_package CMakeLists; shared and static); the .deb
# unpacked with dpkg-deb -x. Label: install.
set(_install_py ${CMAKE_CURRENT_SOURCE_DIR}/integration/install/test_install.py)
set(_install_flags "")
if(SELFCAL_SANITIZE)
  set(_install_flags -fsanitize=address,undefined)  # the examples link the sanitized library
endif()
foreach(case install deb)
  add_test(NAME install_${case}
    COMMAND ${SELFCAL_PYTHON3} ${_install_py} ${case} ${PROJECT_BINARY_DIR} ${PROJECT_SOURCE_DIR}
            ${CMAKE_CURRENT_BINARY_DIR}/tmp/install_${case} ${PROJECT_VERSION} ${_install_flags})
  set_tests_properties(install_${case} PROPERTIES TIMEOUT 600 LABELS "integration;install")
endforeach()
