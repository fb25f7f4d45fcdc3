# mpi.cmake — images that split, merge and resume (issue 16, docs/distributed.md): in one process
# (test_distributed: crops, pieces, tiles, checkpoints), through the CLI (test_split.sh: merge's
# exit codes, a render killed and resumed), and across MPI ranks (test_mpi.sh), which runs only
# when CMake found MPI.
pn_add_test(test_distributed)
add_test(NAME test_split
         COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/test_split.sh $<TARGET_FILE:penumbra_cli> ${CMAKE_SOURCE_DIR})
set_tests_properties(test_split PROPERTIES TIMEOUT 120)
if(PN_HAVE_MPI)
  add_test(NAME test_mpi
           COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/test_mpi.sh $<TARGET_FILE:penumbra_cli> ${CMAKE_SOURCE_DIR}
                   ${MPIEXEC_EXECUTABLE})
  set_tests_properties(test_mpi PROPERTIES TIMEOUT 180)
  # Open MPI keeps allocations until exit that LeakSanitizer would report as ours.
  if(PN_SANITIZE)
    set_tests_properties(test_mpi PROPERTIES ENVIRONMENT "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1")
  endif()
else()
  message(STATUS "penumbra: MPI not found, test_mpi not built")
endif()
