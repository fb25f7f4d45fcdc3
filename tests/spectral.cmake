# Spectral mode's data, RGB upsampling and wavelength sampling (issue 20).
pn_add_test(test_spectral)
pn_add_test(test_spectral_transport)
# XYZ and melanopic_edi outputs, tabulated emission spectra (issue 20)
pn_add_test(test_spectral_outputs)
