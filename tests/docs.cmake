# docs.cmake — the docs pages' option tables against the method table: check_method_docs (in
# registry.cmake) compares them; check_method_docs_selftest shows that comparison can fail, on a
# copy of the pages given a foreign flag and missing one.
add_test(NAME check_method_docs_selftest
         COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/check_method_docs.sh --self-test ${CMAKE_SOURCE_DIR}
                 $<TARGET_FILE:penumbra_cli>)
