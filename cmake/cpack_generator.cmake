# Read by cpack once per generator (CPACK_PROJECT_CONFIG_FILE), CPACK_GENERATOR set to the one
# running. The .tar.gz is a /usr/local tree (usr/local/bin/selfcal, ...; unpack with
# `sudo tar -xzf selfcal-<version>-Linux.tar.gz -C /`): the files that name installed paths
# (selfcald.service, selfcald.8; cmake/install_paths.cmake) are filled in for /usr/local, where
# they land, not for cpack's temporary staging folder.
if(CPACK_GENERATOR STREQUAL "TGZ")
  set(CPACK_SET_DESTDIR ON)
  set(CPACK_PACKAGING_INSTALL_PREFIX "/usr/local")
  # with CPACK_SET_DESTDIR cpack installs to CPACK_INSTALL_PREFIX, else to the prefix the build
  # was configured with (a -DCMAKE_INSTALL_PREFIX=/opt/x build made an opt/x tree)
  set(CPACK_INSTALL_PREFIX "/usr/local")
  set(CPACK_INCLUDE_TOPLEVEL_DIRECTORY OFF)
endif()

# The .deb: man pages gzipped, as Debian policy asks (man reads both), by a script run on the
# staging tree before it is packed (CPACK_PRE_BUILD_SCRIPTS); CPack's ldconfig scripts taken out
# of the library's package after (CPACK_POST_BUILD_SCRIPTS: the ldconfig trigger does that work).
if(CPACK_GENERATOR STREQUAL "DEB")
  set(CPACK_PRE_BUILD_SCRIPTS "${CMAKE_CURRENT_LIST_DIR}/cpack_gzip_man.cmake")
  set(CPACK_POST_BUILD_SCRIPTS "${CMAKE_CURRENT_LIST_DIR}/deb/drop_ldconfig_scripts.cmake")
endif()
