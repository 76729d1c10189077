# Files that name installed paths (selfcald.service, selfcald.8) are filled in when they are
# installed, for the prefix they are installed to — `cmake --install BUILD --prefix P`, or
# cpack's /usr for the .deb — not for the prefix configured (CMAKE_INSTALL_PREFIX at configure
# time, /usr/local by default): a unit naming /usr/local/bin/selfcald in a package that installs
# /usr/bin/selfcald cannot start.
#
# selfcal_install_with_paths(TEMPLATE OUTPUT DESTINATION COMPONENT): TEMPLATE is configured now (@ONLY)
# with everything but @CMAKE_INSTALL_FULL_BINDIR@, @CMAKE_INSTALL_FULL_SYSCONFDIR@,
# @CMAKE_INSTALL_FULL_DOCDIR@ and @SELFCALD_MAN_URL@ (the unit's link to selfcald(8)), which are filled in at install time by GNUInstallDirs' rules for
# the actual prefix (the system configuration folder of the prefixes / and /usr is /etc, of
# /opt/X /etc/opt/X), and installed to DESTINATION (relative to the prefix, or absolute) as part
# of COMPONENT (the package: cmake/packaging.cmake). DESTINATION may itself name
# <CMAKE_INSTALL_FULL_SYSCONFDIR> (and the other two), filled in the same way. With KEEP_EXISTING a file already installed
# there is left as it is (a configuration the user edited; dpkg handles its conffiles itself).

function(selfcal_install_with_paths template output destination component)
  set(keep 0)
  if("KEEP_EXISTING" IN_LIST ARGN)
    set(keep 1)
  endif()
  foreach(dir BINDIR SYSCONFDIR DOCDIR)
    set(CMAKE_INSTALL_FULL_${dir} "@CMAKE_INSTALL_FULL_${dir}@")
  endforeach()
  set(SELFCALD_MAN_URL "@SELFCALD_MAN_URL@")
  configure_file(${template} ${output}.in @ONLY)
  install(CODE "
    set(_selfcal_prefix \"\${CMAKE_INSTALL_PREFIX}\")
    foreach(_dir BINDIR SYSCONFDIR DOCDIR)
      if(_dir STREQUAL BINDIR)
        set(_rel \"${CMAKE_INSTALL_BINDIR}\")
      elseif(_dir STREQUAL SYSCONFDIR)
        set(_rel \"${CMAKE_INSTALL_SYSCONFDIR}\")
      else()
        set(_rel \"${CMAKE_INSTALL_DOCDIR}\")
      endif()
      if(IS_ABSOLUTE \"\${_rel}\")
        set(_abs \"\${_rel}\")
      elseif(_dir STREQUAL SYSCONFDIR AND _selfcal_prefix MATCHES \"^/(usr/?)?$\")
        set(_abs \"/\${_rel}\")
      elseif(_dir STREQUAL SYSCONFDIR AND _selfcal_prefix MATCHES \"^/opt/\")
        set(_abs \"/\${_rel}\${_selfcal_prefix}\")
      elseif(_selfcal_prefix MATCHES \"^/$\")
        set(_abs \"/usr/\${_rel}\")
      else()
        string(REGEX REPLACE \"/+$\" \"\" _p \"\${_selfcal_prefix}\")
        set(_abs \"\${_p}/\${_rel}\")
      endif()
      set(CMAKE_INSTALL_FULL_\${_dir} \"\${_abs}\")
    endforeach()
    # the daemon's manual as the unit's Documentation=: man:selfcald(8) where man(1) finds it
    # (the prefixes /usr, /usr/local), else the installed file (systemd-analyze verify checks
    # every man: page it names)
    if(_selfcal_prefix MATCHES \"^/(usr/?|usr/local/?)?$\")
      set(SELFCALD_MAN_URL \"man:selfcald(8)\")
    else()
      string(REGEX REPLACE \"/+$\" \"\" _p \"\${_selfcal_prefix}\")
      set(SELFCALD_MAN_URL \"file:\${_p}/${CMAKE_INSTALL_MANDIR}/man8/selfcald.8\")
    endif()
    configure_file(\"${output}.in\" \"${output}\" @ONLY)
    set(_dest \"${destination}\")
    foreach(_dir BINDIR SYSCONFDIR DOCDIR)
      string(REPLACE \"<CMAKE_INSTALL_FULL_\${_dir}>\" \"\${CMAKE_INSTALL_FULL_\${_dir}}\" _dest \"\${_dest}\")
    endforeach()
    if(NOT IS_ABSOLUTE \"\${_dest}\")
      set(_dest \"\${CMAKE_INSTALL_PREFIX}/\${_dest}\")
    endif()
    get_filename_component(_name \"${output}\" NAME)
    if(${keep} AND EXISTS \"\$ENV{DESTDIR}\${_dest}/\${_name}\")
      message(STATUS \"Kept (not overwritten): \$ENV{DESTDIR}\${_dest}/\${_name}\")
    else()
      file(INSTALL DESTINATION \"\${_dest}\" TYPE FILE FILES \"${output}\")
    endif()
  " COMPONENT ${component})
endfunction()
