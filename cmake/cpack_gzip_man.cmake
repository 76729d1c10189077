# Run by cpack (CPACK_PRE_BUILD_SCRIPTS, cmake/cpack_generator.cmake) on the .deb's staging tree:
# every man page share/man/man*/NAME becomes NAME.gz (gzip -9n: no name or time stamp in the
# header, so that the package is reproducible), as Debian policy 12.1 asks.
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
