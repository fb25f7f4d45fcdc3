# robust.cmake — hostile files and outputs never lost or misplaced (issue 19).
pn_add_test(test_robust)
target_compile_definitions(test_robust PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_robust penumbra_cli)
set_tests_properties(test_robust PROPERTIES TIMEOUT 120)
# The fuzz targets' corpora replayed through the real readers (tests/fuzz/CMakeLists.txt).
if(NOT PN_FUZZ)
  add_subdirectory(${CMAKE_CURRENT_SOURCE_DIR}/fuzz ${CMAKE_CURRENT_BINARY_DIR}/fuzz)
endif()
# Allocation-failure injection: only the sanitizer build has the hook (src/core/alloc_hook.h).
if(PN_SANITIZE)
  pn_add_test(test_alloc_failures)
  set_tests_properties(test_alloc_failures PROPERTIES TIMEOUT 300)
endif()
