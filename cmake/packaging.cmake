# Packages with CPack, from a configured build:
#   cmake --build BUILD && (cd BUILD && cpack -G "DEB;TGZ")
# DEB: one package per component, as Debian packages a C library with its tools:
#   libselfcal<soversion>  the shared library (libselfcal0.4 for libselfcal.so.0.4), with the ldconfig trigger
#   libselfcal-dev         headers, libselfcal.a, the libselfcal.so link, selfcal.pc, the CMake package
#   selfcal                the command line, selfcal(1), the documentation and examples
#   selfcald               the daemon, selfcald(8), its systemd unit and /etc/selfcal/selfcald.conf (a conffile)
#   selfcal-linuxcnc       the HAL component selfcal_xy and selfcal_xy(9) (when built)
# each <name>_<version>_<arch>.deb, installing under /usr (the library in the multiarch folder).
# TGZ: one selfcal-<version>-Linux.tar.gz, a /usr/local tree of all of them (cpack_generator.cmake).
set(CPACK_PACKAGE_NAME selfcal)
set(CPACK_PACKAGE_VENDOR "selfcal")
# the Maintainer field of the .deb: set it to a real address for a package that leaves the lab
set(SELFCAL_PACKAGE_CONTACT "selfcal maintainers <selfcal@localhost>" CACHE STRING
    "Maintainer of the packages (Name <address>)")
set(CPACK_PACKAGE_CONTACT "${SELFCAL_PACKAGE_CONTACT}")
# programs and libraries stripped of their symbols and debug information (and so of the build's
# paths) in both packages
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_PACKAGE_DESCRIPTION "Grid plate self-calibration (Ye, double shift, least squares),
straightness by the two-set two-point method, a compact correction table and
selfcald, a daemon correcting live positions over Modbus TCP/RTU and SocketCAN.")
set(CPACK_RESOURCE_FILE_README ${PROJECT_SOURCE_DIR}/README.md)
set(CPACK_RESOURCE_FILE_LICENSE ${PROJECT_SOURCE_DIR}/LICENSE)
set(CPACK_GENERATOR "DEB;TGZ")
set(CPACK_SOURCE_GENERATOR "")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
# The shared libraries the programs and libselfcal.so link, with the versions they need, from
# dpkg-shlibdeps (dpkg-dev); CHOLMOD is loaded at run time (dlopen, libcholmod.so.<major> of the
# headers built with: libcholmod3 on Debian 12), so it is named here.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# the programs' libselfcal.so.<soversion> is found in the lib package's staging tree (dpkg-shlibdeps
# runs in each component's own; the dependency on that package comes from _DEPENDS below)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS_PRIVATE_DIRS "../lib/usr/${CMAKE_INSTALL_LIBDIR}")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_PROJECT_CONFIG_FILE ${CMAKE_CURRENT_LIST_DIR}/cpack_generator.cmake)
# each package's usr/share/doc/<package>/copyright (cpack_gzip_man.cmake)
set(CPACK_SELFCAL_COPYRIGHT ${PROJECT_SOURCE_DIR}/packaging/copyright)
# each package's lintian overrides, each explained in its file (cmake/deb/lintian/<component>)
set(CPACK_SELFCAL_LINTIAN_DIR ${CMAKE_CURRENT_LIST_DIR}/deb/lintian)

set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_ENABLE_COMPONENT_DEPENDS ON) # Depends: libselfcal0.<minor> (= version) from _DEPENDS below
set(CPACK_COMPONENTS_ALL lib dev cli daemon)
if(SELFCAL_HAL_MODULE)
  list(APPEND CPACK_COMPONENTS_ALL linuxcnc)
endif()
set(SELFCAL_DEB_LIB_PACKAGE libselfcal${SELFCAL_SOVERSION})

# the shared library: its package is named after its soname (Debian policy 8.1); a shlibs file
# so that a package linking it needs this version or later; the dynamic linker's cache refreshed
# by dpkg's ldconfig trigger (policy 8.1.1; control files in deb/lib). CHOLMOD is loaded at run
# time (dlopen, libcholmod.so.<major> of the headers built with: libcholmod3 on Debian 12), so it
# is named here; dpkg-shlibdeps finds the rest (FFTW, libc) with their versions.
set(CPACK_DEBIAN_LIB_PACKAGE_NAME ${SELFCAL_DEB_LIB_PACKAGE})
set(CPACK_DEBIAN_LIB_PACKAGE_SECTION libs)
set(CPACK_DEBIAN_LIB_PACKAGE_DEPENDS "libcholmod${SELFCAL_CHOLMOD_MAJOR}")
set(CPACK_DEBIAN_LIB_PACKAGE_CONTROL_EXTRA ${CMAKE_CURRENT_LIST_DIR}/deb/triggers)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS_POLICY ">=")
set(CPACK_COMPONENT_LIB_DESCRIPTION "self-calibration of precision XY stages (shared library)
libselfcal separates a stage's error map from an uncalibrated grid plate's
errors (Ye, double shift, optimal least squares with every node's
uncertainty), computes straightness by the two-set two-point method, and
writes and applies a compact correction table.
.
This package holds the shared library.")

# headers and the static library; linking libselfcal.a needs FFTW's development files
set(CPACK_DEBIAN_DEV_PACKAGE_NAME libselfcal-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_COMPONENT_DEV_DEPENDS lib)
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "libfftw3-dev")
set(CPACK_DEBIAN_DEV_PACKAGE_SUGGESTS "pkg-config")
set(CPACK_COMPONENT_DEV_DESCRIPTION "self-calibration of precision XY stages (development files)
libselfcal separates a stage's error map from an uncalibrated grid plate's
errors, computes straightness profiles and writes and applies a compact
correction table.
.
This package holds the headers, the static library, selfcal.pc and the
CMake package (find_package(selfcal)).")

set(CPACK_DEBIAN_CLI_PACKAGE_NAME selfcal)
set(CPACK_DEBIAN_CLI_PACKAGE_SECTION science)
set(CPACK_COMPONENT_CLI_DEPENDS lib)
set(CPACK_DEBIAN_CLI_PACKAGE_SUGGESTS "chromium")
set(CPACK_COMPONENT_CLI_DESCRIPTION "self-calibration of precision XY stages (command line)
selfcal simulates, calibrates and plans grid plate and straightness
measurements, imports measuring machines' exports, builds and inspects
correction tables, exports them to CNC and motion controllers, and draws
error maps and uncertainty curves. Reports are HTML (PDF through Chromium).")

set(CPACK_DEBIAN_DAEMON_PACKAGE_NAME selfcald)
set(CPACK_DEBIAN_DAEMON_PACKAGE_SECTION science)
set(CPACK_COMPONENT_DAEMON_DEPENDS lib)
# /etc/selfcal/selfcald.conf: dpkg keeps the administrator's changes across upgrades
set(CPACK_DEBIAN_DAEMON_PACKAGE_CONTROL_EXTRA ${CMAKE_CURRENT_LIST_DIR}/deb/conffiles)
set(CPACK_COMPONENT_DAEMON_DESCRIPTION "self-calibration of precision XY stages (correction daemon)
selfcald loads a correction table written by selfcal and corrects live XY
positions read over Modbus TCP, Modbus RTU or SocketCAN, in constant time
and without allocating after start. The package holds its systemd unit
(not enabled) and /etc/selfcal/selfcald.conf.")

# the HAL component compiles the correction core in: it needs LinuxCNC, not libselfcal
set(CPACK_DEBIAN_LINUXCNC_PACKAGE_NAME selfcal-linuxcnc)
set(CPACK_DEBIAN_LINUXCNC_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_LINUXCNC_PACKAGE_DEPENDS "linuxcnc-uspace")
set(CPACK_COMPONENT_LINUXCNC_DESCRIPTION "self-calibration of precision XY stages (LinuxCNC component)
selfcal_xy is a LinuxCNC realtime HAL component that corrects X and Y in the
servo thread with a table written by selfcal, with the same correction core
as the selfcald daemon. Built against the LinuxCNC of the build machine.")
include(CPack)
