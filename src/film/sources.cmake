# film files; a file is compiled once it exists.
foreach(f metrics.c false_color.c downsample.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/film/${f})
  endif()
endforeach()
