# Module layering: include rules between src/shade, src/lights, src/scene and src/integrators, and
# no eye ray traced by an integrator (check_layers.sh lists them), and a self-test that each rule
# rejects a planted violation.
add_test(NAME check_layers COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/check_layers.sh ${CMAKE_SOURCE_DIR})
add_test(NAME check_layers_self_test COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/check_layers.sh --self-test)
