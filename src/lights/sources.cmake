list(APPEND PN_SOURCES
  src/lights/lights.c
  src/lights/light_sample.c
  src/lights/light_pdf.c
)
