# cli.cmake — end-to-end tests of the `penumbra` program: they run the built binary.
pn_add_test(test_cli)
target_compile_definitions(test_cli PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_cli penumbra_cli)
set_tests_properties(test_cli PROPERTIES TIMEOUT 120)
