# The spectral module's source files (listed by hand: no globbing): colorimetric data, RGB to
# spectrum upsampling and wavelength sampling for spectral mode.
list(APPEND PN_SOURCES
  src/spectral/cie.c
  src/spectral/cie_data.c
  src/spectral/melanopic.c
  src/spectral/melanopic_data.c
  src/spectral/metals.c
  src/spectral/metals_data.c
  src/spectral/rgb2spec.c
  src/spectral/transport.c
  src/spectral/wavelengths.c
)
