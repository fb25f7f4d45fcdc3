# install.cmake — installs the built library into a scratch prefix and builds a small outside
# program against it, once through penumbra.pc and once through find_package(penumbra).
# run.sh brings penumbra and penumbra_cli up to date itself before installing, so the test also
# works when only part of the tree has been built.
set(PN_INSTALL_TEST_ENV "CMAKE=${CMAKE_COMMAND}" "CC=${CMAKE_C_COMPILER}")
if(PN_SANITIZE)
  # The installed library then needs the sanitizer runtimes: build the consumers the same way.
  list(APPEND PN_INSTALL_TEST_ENV "PN_CONSUMER_FLAGS=-fsanitize=address,undefined")
endif()
add_test(NAME test_install
         COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/install/run.sh ${CMAKE_BINARY_DIR}
                 ${CMAKE_CURRENT_BINARY_DIR}/install-work)
set_tests_properties(test_install PROPERTIES
  LABELS slow
  TIMEOUT 300
  ENVIRONMENT "${PN_INSTALL_TEST_ENV}")
