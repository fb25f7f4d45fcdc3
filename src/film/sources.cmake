# The film module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/film/aovs.c
  src/film/metrics.c
  src/film/false_color.c
  src/film/downsample.c
)
