# Sobol' points, sample warps, spherical rectangles, sphere cones, tabulated distributions.
pn_add_test(test_sampling)
