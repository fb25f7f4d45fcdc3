# The render module's source files (listed by hand: no globbing): what drivers and integrators
# share — the render job, camera, eye paths and the progress path (see render/batch.h).
list(APPEND PN_SOURCES
  src/render/camera.c
  src/render/eye_path.c
  src/render/progress.c
  src/render/shadow.c
  src/render/stats.c
)
