# integrators files; a file is compiled once it exists.
foreach(f registry.c reference.c ias_math.c ias.c vpl_common.c vpl.c lightcuts.c illumcut.c illumcut_point_tree.c
        reference_direct.c contour_math.c contour.c contour_render.c contour_mc.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/integrators/${f})
  endif()
endforeach()
