# lights files; a file is compiled once it exists.
foreach(f lights.c light_sample.c light_pdf.c cluster_tree.c env_regions.c light_bvh.c vpl.c light_tree.c projection.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/lights/${f})
  endif()
endforeach()
