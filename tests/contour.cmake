pn_add_test(test_contour)
# The CLI options of the contour integrators: runs the built binary.
pn_add_test(test_contour_cli)
target_compile_definitions(test_contour_cli PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_contour_cli penumbra_cli)
