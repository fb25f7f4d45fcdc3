# design.cmake — lighting design (docs/lighting-design.md): sky, calculation points, glazing,
# false colour, the CLI's grids and the office demo against closed forms.
pn_add_test(test_design)
target_compile_definitions(test_design PRIVATE PN_CLI_PATH="$<TARGET_FILE:penumbra_cli>")
add_dependencies(test_design penumbra_cli)
target_link_libraries(test_design PRIVATE PkgConfig::CJSON)
target_compile_options(test_design PRIVATE -Wno-double-promotion)
# The office demo's work-plane grid against the closed form summed over its 24 spots.
pn_add_test(test_design_office)
target_compile_options(test_design_office PRIVATE -Wno-double-promotion)
# Issue 17's gaps: glazing in contour / contour-mc, the illuminance AOV of ias, contour,
# contour-mc and illumcut, thin-glass spheres.
pn_add_test(test_design_aov)
target_compile_options(test_design_aov PRIVATE -Wno-double-promotion)
