# The integrators module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/integrators/registry.c
  src/integrators/reference.c
  src/integrators/ias_math.c
  src/integrators/ias_speed.c
  src/integrators/ias_ratio.c
  src/integrators/ias_mis.c
  src/integrators/ias_guide.c
  src/integrators/ias.c
  src/integrators/vpl_common.c
  src/integrators/vpl.c
  src/integrators/lightcuts.c
  src/integrators/illumcut.c
  src/integrators/reference_direct.c
  src/integrators/contour_math.c
  src/integrators/contour.c
  src/integrators/contour_render.c
  src/integrators/contour_mc.c
  src/integrators/point_eval.c
)
