list(APPEND PN_SOURCES
  src/driver/camera.c
  src/driver/eye_path.c
  src/driver/render.c
  src/driver/progress.c
  src/driver/progressive.c
  src/driver/dcm.c
  src/driver/painter.c
)
