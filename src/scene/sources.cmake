# The scene module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/scene/scene_load.c
  src/scene/ply.c
  src/scene/tokenizer.c
  src/scene/params.c
  src/scene/parser.c
  src/scene/shapes.c
  src/scene/materials.c
  src/scene/texture.c
  src/scene/mipmap.c
  src/scene/spectrum.c
  src/scene/lightdefs.c
  src/scene/photometry.c
  src/scene/sky.c
)
