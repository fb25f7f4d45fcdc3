# Scene files; a file is compiled once it exists (the parser is written in parts).
foreach(f scene_load.c ply.c tokenizer.c params.c parser.c shapes.c materials.c texture.c
          spectrum.c lightdefs.c)
  if(EXISTS ${CMAKE_CURRENT_LIST_DIR}/${f})
    list(APPEND PN_SOURCES src/scene/${f})
  endif()
endforeach()
