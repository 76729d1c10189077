# Read by cpack once per generator (CPACK_PROJECT_CONFIG_FILE), CPACK_GENERATOR set to the one
# running. The .tar.gz is a /usr/local tree (usr/local/bin/selfcal, ...; unpack with
# `sudo tar -xzf selfcal-<version>-Linux.tar.gz -C /`): the files that name installed paths
# (selfcald.service, selfcald.8; cmake/install_paths.cmake) are filled in for /usr/local, where
# they land, not for cpack's temporary staging folder.
if(CPACK_GENERATOR STREQUAL "TGZ")
  set(CPACK_SET_DESTDIR ON)
  set(CPACK_PACKAGING_INSTALL_PREFIX "/usr/local")
  set(CPACK_INCLUDE_TOPLEVEL_DIRECTORY OFF)
endif()
