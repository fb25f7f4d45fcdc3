# The driver module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/driver/render.c
  src/driver/progressive.c
  src/driver/dcm.c
  src/driver/painter.c
  src/driver/points.c
  src/driver/tiles.c
  src/driver/checkpoint.c
  src/driver/mpi.c
)
