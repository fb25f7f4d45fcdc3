# The lights module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/lights/lights.c
  src/lights/light_sample.c
  src/lights/light_pdf.c
  src/lights/cluster_tree.c
  src/lights/env_regions.c
  src/lights/light_bvh.c
  src/lights/vpl.c
  src/lights/light_tree.c
  src/lights/projection.c
  src/lights/photometric.c
)
