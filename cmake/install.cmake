# Installation (GNUInstallDirs layout): `cmake --install BUILD --prefix P` gives
#   P/bin/selfcal, P/bin/selfcald           programs; RPATH $ORIGIN/../<libdir>: they run from any
#                                           prefix (even a moved one) without LD_LIBRARY_PATH
#   P/<libdir>/libselfcal.so{,.0,.0.x.y}    shared library (SONAME libselfcal.so.<major>)
#   P/<libdir>/libselfcal.a                 static library
#   P/include/selfcal/*.h                   public headers (+ the generated version.h)
#   P/<libdir>/pkgconfig/selfcal.pc         pkg-config
#   P/<libdir>/cmake/selfcal/               CMake package: find_package(selfcal) -> selfcal::selfcal,
#                                           selfcal::selfcal_static
#   P/share/man/man1/selfcal.1, man8/selfcald.8
#   P/lib/systemd/system/selfcald.service   with P's paths filled in at install time (install_paths.cmake)
#   P/share/doc/selfcal/                    README, docs/, selfcald.conf.example, examples/,
#                                           python/README.md, runtime/selfcald.dbc (the links hold),
#                                           LICENSE and copyright (Debian's format: the notices of
#                                           the code compiled in from fast_float and Dragonbox)
# Adding something: an install() rule next to the target that makes it (programs: call
# selfcal_install_program(TARGET) from the folder that defines TARGET).
include(CMakePackageConfigHelpers)

set(SELFCAL_CMAKE_PACKAGE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/selfcal)

# ---- the library: both builds, headers, CMake package, pkg-config ----
# Components (one .deb each, cmake/packaging.cmake): lib (the shared library), dev (headers, the
# static library, the libselfcal.so link, pkg-config and CMake files), cli (selfcal, its manual
# and the documentation), daemon (selfcald, its manual, unit and configuration), linuxcnc (the HAL
# component: linuxcnc/CMakeLists.txt).
install(TARGETS selfcal selfcal_static EXPORT selfcalTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT lib NAMELINK_COMPONENT dev
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT lib
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${SELFCAL_INCLUDE_DIR}/selfcal DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
  COMPONENT dev FILES_MATCHING PATTERN "*.h")
install(FILES ${SELFCAL_GENERATED_INCLUDE_DIR}/selfcal/version.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/selfcal COMPONENT dev)

install(EXPORT selfcalTargets NAMESPACE selfcal:: DESTINATION ${SELFCAL_CMAKE_PACKAGE_DIR}
  COMPONENT dev)
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/selfcalConfig.cmake.in
  ${PROJECT_BINARY_DIR}/cmake/selfcalConfig.cmake
  INSTALL_DESTINATION ${SELFCAL_CMAKE_PACKAGE_DIR})
# as the soname (libselfcal/CMakeLists.txt): 0.x versions are compatible within their minor only
if(PROJECT_VERSION_MAJOR EQUAL 0)
  set(_selfcal_compat SameMinorVersion)
else()
  set(_selfcal_compat SameMajorVersion)
endif()
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/selfcalConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY ${_selfcal_compat})
install(FILES ${PROJECT_BINARY_DIR}/cmake/selfcalConfig.cmake
              ${PROJECT_BINARY_DIR}/cmake/selfcalConfigVersion.cmake
  DESTINATION ${SELFCAL_CMAKE_PACKAGE_DIR} COMPONENT dev)

# selfcal.pc finds its prefix from its own folder: as many ".." as <libdir>/pkgconfig has parts.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  message(FATAL_ERROR "CMAKE_INSTALL_LIBDIR must be relative to the prefix (is ${CMAKE_INSTALL_LIBDIR})")
endif()
string(REGEX REPLACE "[^/]+" ".." SELFCAL_PC_UP "${CMAKE_INSTALL_LIBDIR}/pkgconfig")
configure_file(${CMAKE_CURRENT_LIST_DIR}/selfcal.pc.in ${PROJECT_BINARY_DIR}/selfcal.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/selfcal.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig COMPONENT dev)
# Installed under /usr (the .deb, a distribution's prefix), the prefix is written out: pkg-config
# leaves out its system folders (-I/usr/include, -L/usr/lib) only when they are spelled so, not
# as /usr/lib/pkgconfig/../../include. Elsewhere the file stays relocatable.
install(CODE "
  if(CMAKE_INSTALL_PREFIX MATCHES \"^/usr/?$\")
    set(_pc \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_LIBDIR}/pkgconfig/selfcal.pc\")
    file(READ \"\${_pc}\" _text)
    string(REGEX REPLACE \"\nprefix=[^\n]*\" \"\nprefix=/usr\" _text \"\${_text}\")
    string(REPLACE \"Relocatable: the prefix is\n# found from this file's own folder, so a moved install tree still works.\"
           \"Installed under /usr: the\n# prefix written out, as pkg-config recognises its system folders.\" _text \"\${_text}\")
    file(WRITE \"\${_pc}\" \"\${_text}\")
  endif()
" COMPONENT dev)

# ---- man pages (roff sources in docs/man/, the version filled in) ----
# (selfcald.8 names installed paths: filled in for the prefix it is installed to)
foreach(page selfcal.1:cli selfcald.8:daemon)
  string(REGEX REPLACE ":.*" "" name ${page})
  string(REGEX REPLACE ".*:" "" component ${page})
  string(REGEX REPLACE ".*\\.([0-9])$" "\\1" section ${name})
  selfcal_install_with_paths(${PROJECT_SOURCE_DIR}/docs/man/${name}.in ${PROJECT_BINARY_DIR}/man/${name}
    ${CMAKE_INSTALL_MANDIR}/man${section} ${component})
endforeach()

# ---- documentation and the example program (with the command line: the package selfcal) ----
install(FILES ${PROJECT_SOURCE_DIR}/README.md ${PROJECT_SOURCE_DIR}/LICENSE
              ${PROJECT_SOURCE_DIR}/packaging/copyright DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT cli)
# the source tree's layout, so that the README's and the docs' relative links work installed too
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs
  COMPONENT cli FILES_MATCHING PATTERN "*.md" PATTERN "man" EXCLUDE)
install(FILES ${PROJECT_SOURCE_DIR}/python/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR}/python COMPONENT cli)
install(FILES ${PROJECT_SOURCE_DIR}/runtime/selfcald.dbc DESTINATION ${CMAKE_INSTALL_DOCDIR}/runtime COMPONENT cli)
install(FILES ${PROJECT_SOURCE_DIR}/examples/grid_node.c ${PROJECT_SOURCE_DIR}/examples/Makefile
              ${PROJECT_SOURCE_DIR}/examples/CMakeLists.txt
  DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples COMPONENT cli)
install(FILES ${PROJECT_SOURCE_DIR}/examples/python/calibrate_stage.py
  DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples/python COMPONENT cli)
