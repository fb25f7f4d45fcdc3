# core files; a file is compiled once it exists.
foreach(f error.c vecmath.c context.c sobol.c sampling.c threadpool.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/core/${f})
  endif()
endforeach()
