list(APPEND PN_SOURCES
  src/driver/camera.c
  src/driver/eye_path.c
  src/driver/render.c
)
