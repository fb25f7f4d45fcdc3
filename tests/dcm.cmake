# dcm.cmake — the progressive drivers of issue 6 (dcm, painter, uniform, full); runs the CLI too.
pn_add_test(test_dcm)
target_compile_definitions(test_dcm PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_dcm penumbra_cli)
set_tests_properties(test_dcm PROPERTIES TIMEOUT 300)
