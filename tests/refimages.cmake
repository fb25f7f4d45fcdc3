pn_add_test(test_refimages slow)
