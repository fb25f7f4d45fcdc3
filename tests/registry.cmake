# registry.cmake — the method table and what is generated from it (test_registry), and the rule
# that no method name is spelled outside the table and the method's own files.
pn_add_test(test_registry)
target_compile_definitions(test_registry PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
target_link_libraries(test_registry PRIVATE PkgConfig::CJSON)
add_dependencies(test_registry penumbra_cli)
set_tests_properties(test_registry PROPERTIES TIMEOUT 300)
add_test(NAME check_method_names
         COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/check_method_names.sh ${CMAKE_SOURCE_DIR} $<TARGET_FILE:penumbra_cli>)
# docs/options.md is generated from the table (penumbra methods --markdown) and must match it.
add_test(NAME docs_options_current
         COMMAND sh -c "\"$1\" methods --markdown | cmp - \"$2\"" sh $<TARGET_FILE:penumbra_cli>
                 ${CMAKE_SOURCE_DIR}/docs/options.md)
# Each docs/methods page lists exactly the options the table declares for its methods.
add_test(NAME check_method_docs
         COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/check_method_docs.sh ${CMAKE_SOURCE_DIR} $<TARGET_FILE:penumbra_cli>)
