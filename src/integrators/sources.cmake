list(APPEND PN_SOURCES
  src/integrators/reference.c
)
