# Chi-square goodness-of-fit tests of pn_light_sample_point for every area-light kind and for
# environment maps, plus per-sample consistency checks (pdf, direction, point on the light).
pn_add_test(test_light_sampling)
