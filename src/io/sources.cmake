# The io module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/io/image.c
  src/io/image_ops.c
  src/io/exr.c
  src/io/pfm.c
  src/io/ldr.c
  src/io/png_jpeg.c
  src/io/write.c
  src/io/image_merge.c
)
