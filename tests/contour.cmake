pn_add_test(test_contour)
