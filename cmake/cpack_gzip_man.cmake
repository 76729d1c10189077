# Run by cpack (CPACK_PRE_BUILD_SCRIPTS, cmake/cpack_generator.cmake) on the .deb's staging tree:
# every man page share/man/man*/NAME becomes NAME.gz (gzip -9n: no name or time stamp in the
# header, so that the package is reproducible), as Debian policy 12.1 asks; and the native
# package's changelog, share/doc/selfcal/changelog.gz (policy 12.7), one entry for the version
# (dated SOURCE_DATE_EPOCH when set, for reproducible packages); the HAL module stripped.
find_program(_gzip gzip REQUIRED)
file(GLOB_RECURSE _pages LIST_DIRECTORIES false "${CPACK_TEMPORARY_DIRECTORY}/*/share/man/man*/*")
foreach(_page IN LISTS _pages)
  if(NOT _page MATCHES "\\.gz$")
    execute_process(COMMAND ${_gzip} -9nf "${_page}" RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0)
      message(FATAL_ERROR "gzip ${_page} failed (${_rc})")
    endif()
  endif()
endforeach()

file(GLOB _docdirs LIST_DIRECTORIES true "${CPACK_TEMPORARY_DIRECTORY}/*/share/doc/selfcal")
if(_docdirs)
  list(GET _docdirs 0 _docdir)
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
  file(WRITE "${_docdir}/changelog"
       "selfcal (${CPACK_PACKAGE_VERSION}) unstable; urgency=medium\n\n"
       "  * Release ${CPACK_PACKAGE_VERSION} (built with CPack from the project's sources; the\n"
       "    history is the project's git log).\n\n"
       " -- ${CPACK_PACKAGE_CONTACT}  ${_date}\n")
  execute_process(COMMAND ${_gzip} -9nf "${_docdir}/changelog" RESULT_VARIABLE _rc)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "gzip changelog failed (${_rc})")
  endif()
endif()

# the LinuxCNC component, installed as a file (halcompile builds it): stripped as CPACK_STRIP_FILES
# strips the targets (--strip-unneeded keeps the dynamic symbols rtapi_app looks up)
find_program(_strip strip)
file(GLOB_RECURSE _modules LIST_DIRECTORIES false "${CPACK_TEMPORARY_DIRECTORY}/*/lib/linuxcnc/modules/*.so")
foreach(_m IN LISTS _modules)
  if(_strip)
    execute_process(COMMAND ${_strip} --strip-unneeded "${_m}" RESULT_VARIABLE _rc)
    if(NOT _rc EQUAL 0)
      message(FATAL_ERROR "strip ${_m} failed (${_rc})")
    endif()
  endif()
endforeach()
