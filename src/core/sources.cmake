list(APPEND PN_SOURCES
  src/core/error.c
  src/core/vecmath.c
  src/core/context.c
)
