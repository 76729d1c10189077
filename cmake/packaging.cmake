# Packages with CPack: `cpack -G DEB` (selfcal_<version>_<arch>.deb, installs under /usr) and
# `cpack -G TGZ` (selfcal-<version>-Linux.tar.gz, the install tree), from a configured build:
#   cmake --build BUILD && (cd BUILD && cpack -G "DEB;TGZ")
set(CPACK_PACKAGE_NAME selfcal)
set(CPACK_PACKAGE_VENDOR "selfcal")
set(CPACK_PACKAGE_CONTACT "selfcal maintainers <selfcal@localhost>")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "${PROJECT_DESCRIPTION}")
set(CPACK_PACKAGE_DESCRIPTION "Grid plate self-calibration (Ye, double shift, least squares), \
straightness by the two-set two-point method, a compact correction table and selfcald, a daemon \
correcting live positions over Modbus TCP/RTU and SocketCAN.")
set(CPACK_RESOURCE_FILE_README ${PROJECT_SOURCE_DIR}/README.md)
set(CPACK_GENERATOR "DEB;TGZ")
set(CPACK_SOURCE_GENERATOR "")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
# The shared libraries the programs and libselfcal.so need (Debian 12 names).
set(CPACK_DEBIAN_PACKAGE_DEPENDS "libc6, libfftw3-double3, libmodbus5, libcholmod3")
# linuxcnc-uspace: the HAL component selfcal_xy (in /usr/lib/linuxcnc/modules, when built) runs
# only inside LinuxCNC, built against the LinuxCNC version of the build machine.
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "libfftw3-dev, pkg-config, linuxcnc-uspace")
include(CPack)
