# Run by cpack (CPACK_PRE_BUILD_SCRIPTS, cmake/cpack_generator.cmake) on the .deb's staging tree,
# one folder per component (lib, dev, cli, daemon, linuxcnc: cmake/packaging.cmake), each a root
# holding usr/...: every man page share/man/man*/NAME becomes NAME.gz (gzip -9n: no name or time
# stamp in the header, so that the package is reproducible), as Debian policy 12.1 asks; each
# package gets its usr/share/doc/<package>/copyright (policy 12.5) and the native package's
# changelog.gz (policy 12.7), one entry for the version (dated SOURCE_DATE_EPOCH when set, for
# reproducible packages) and its explained lintian overrides; the programs, libraries and the HAL
# module stripped as dh_strip does.
find_program(_gzip gzip REQUIRED)
file(GLOB _roots LIST_DIRECTORIES true "${CPACK_TEMPORARY_DIRECTORY}/*")
if(EXISTS "${CPACK_TEMPORARY_DIRECTORY}/usr")
  set(_roots "${CPACK_TEMPORARY_DIRECTORY}") # a single package
endif()

if(DEFINED ENV{SOURCE_DATE_EPOCH})
  set(_epoch $ENV{SOURCE_DATE_EPOCH})
else()
  string(TIMESTAMP _epoch "%s" UTC)
endif()
execute_process(COMMAND date -u -R -d @${_epoch} OUTPUT_VARIABLE _date
                OUTPUT_STRIP_TRAILING_WHITESPACE RESULT_VARIABLE _rc)
if(NOT _rc EQUAL 0)
  message(FATAL_ERROR "date failed (${_rc})")
endif()

foreach(_root IN LISTS _roots)
  if(NOT IS_DIRECTORY "${_root}/usr")
    continue()
  endif()
  file(GLOB_RECURSE _pages LIST_DIRECTORIES false "${_root}/usr/share/man/*")
  foreach(_page IN LISTS _pages)
    if(NOT _page MATCHES "\\.gz$")
      execute_process(COMMAND ${_gzip} -9nf "${_page}" RESULT_VARIABLE _rc)
      if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "gzip ${_page} failed (${_rc})")
      endif()
    endif()
  endforeach()

  # programs and shared libraries without the compiler's .comment and .note sections (as dh_strip)
  file(GLOB _elves LIST_DIRECTORIES false "${_root}/usr/bin/*" "${_root}/usr/lib/*/*.so.*")
  foreach(_e IN LISTS _elves)
    if(NOT IS_SYMLINK "${_e}")
      execute_process(COMMAND strip --remove-section=.comment --remove-section=.note "${_e}"
                      RESULT_VARIABLE _rc)
      if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "strip ${_e} failed (${_rc})")
      endif()
    endif()
  endforeach()

  # static libraries as dh_strip leaves them: no debug information, no .comment or .note sections
  # (CPACK_STRIP_FILES strips programs and shared libraries only)
  file(GLOB_RECURSE _archives LIST_DIRECTORIES false "${_root}/usr/lib/*.a")
  foreach(_a IN LISTS _archives)
    execute_process(COMMAND strip --strip-debug --remove-section=.comment --remove-section=.note
                            --enable-deterministic-archives "${_a}" RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0)
      message(FATAL_ERROR "strip ${_a} failed (${_rc})")
    endif()
  endforeach()

  # the package this root becomes
  get_filename_component(_component "${_root}" NAME)
  string(TOUPPER "${_component}" _upper)
  if(DEFINED CPACK_DEBIAN_${_upper}_PACKAGE_NAME)
    set(_package "${CPACK_DEBIAN_${_upper}_PACKAGE_NAME}")
  else()
    set(_package "${CPACK_PACKAGE_NAME}")
  endif()
  set(_docdir "${_root}/usr/share/doc/${_package}")
  # the license is in the copyright file (lintian: extra-license-file)
  file(REMOVE "${_docdir}/LICENSE")
  # the package's explained lintian overrides (cmake/deb/lintian/<component>)
  if(EXISTS "${CPACK_SELFCAL_LINTIAN_DIR}/${_component}")
    file(MAKE_DIRECTORY "${_root}/usr/share/lintian/overrides")
    set(PACKAGE "${_package}") # each line's "@PACKAGE@:", the package's own name
    configure_file("${CPACK_SELFCAL_LINTIAN_DIR}/${_component}"
                   "${_root}/usr/share/lintian/overrides/${_package}" @ONLY)
  endif()
  file(MAKE_DIRECTORY "${_docdir}")
  if(NOT EXISTS "${_docdir}/copyright")
    file(COPY "${CPACK_SELFCAL_COPYRIGHT}" DESTINATION "${_docdir}")
  endif()
  file(WRITE "${_docdir}/changelog"
       "selfcal (${CPACK_PACKAGE_VERSION}) unstable; urgency=medium\n\n"
       "  * Release ${CPACK_PACKAGE_VERSION} (built with CPack from the project's sources; the\n"
       "    history is the project's git log).\n\n"
       " -- ${CPACK_PACKAGE_CONTACT}  ${_date}\n")
  execute_process(COMMAND ${_gzip} -9nf "${_docdir}/changelog" RESULT_VARIABLE _rc)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "gzip changelog failed (${_rc})")
  endif()
endforeach()

# the LinuxCNC component, installed as a file (halcompile builds it): stripped as CPACK_STRIP_FILES
# strips the targets (--strip-unneeded keeps the dynamic symbols rtapi_app looks up)
find_program(_strip strip)
foreach(_root IN LISTS _roots)
  file(GLOB _modules LIST_DIRECTORIES false "${_root}/usr/lib/linuxcnc/modules/*.so")
  foreach(_m IN LISTS _modules)
    if(_strip)
      execute_process(COMMAND ${_strip} --strip-unneeded --remove-section=.comment "${_m}" RESULT_VARIABLE _rc)
      if(NOT _rc EQUAL 0)
        message(FATAL_ERROR "strip ${_m} failed (${_rc})")
      endif()
    endif()
  endforeach()
endforeach()
