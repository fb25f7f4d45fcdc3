list(APPEND PN_SOURCES
  src/accel/accel.c
)
