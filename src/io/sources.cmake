# io files; a file is compiled once it exists.
foreach(f image.c image_ops.c exr.c pfm.c ldr.c write.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/io/${f})
  endif()
endforeach()
