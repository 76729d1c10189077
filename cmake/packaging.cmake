# Packages with CPack: `cpack -G DEB` (selfcal_<version>_<arch>.deb, installs under /usr) and
# `cpack -G TGZ` (selfcal-<version>-Linux.tar.gz, a /usr/local tree: cmake/cpack_generator.cmake),
# from a configured build:
#   cmake --build BUILD && (cd BUILD && cpack -G "DEB;TGZ")
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
set(CPACK_DEBIAN_PACKAGE_SECTION science)
# The shared libraries the programs and libselfcal.so link, with the versions they need, from
# dpkg-shlibdeps (dpkg-dev); CHOLMOD is loaded at run time (dlopen, libcholmod.so.<major> of the
# headers built with: libcholmod3 on Debian 12), so it is named here.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON) # a shlibs file for libselfcal.so.<major>: a
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS_POLICY ">=") # package linking it needs this version or later
set(CPACK_DEBIAN_PACKAGE_DEPENDS "libcholmod${SELFCAL_CHOLMOD_MAJOR}")
set(CPACK_PROJECT_CONFIG_FILE ${CMAKE_CURRENT_LIST_DIR}/cpack_generator.cmake)
# libselfcal.so.0.<minor>: the dynamic linker's cache refreshed by dpkg's ldconfig trigger (policy 8.1.1)
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA ${CMAKE_CURRENT_LIST_DIR}/deb/triggers)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
# linuxcnc-uspace: the HAL component selfcal_xy (in /usr/lib/linuxcnc/modules, when built) runs
# only inside LinuxCNC, built against the LinuxCNC version of the build machine.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "libfftw3-dev, pkg-config, linuxcnc-uspace")
include(CPack)
