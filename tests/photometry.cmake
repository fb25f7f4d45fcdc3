# Measured luminaires (IES LM-63, EULUMDAT): reader, lookup, lumens, emission sampling, every
# integrator, bad files (issue 17, items 1-3 and 8).
pn_add_test(test_photometry)
target_compile_definitions(test_photometry PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_photometry penumbra_cli)
