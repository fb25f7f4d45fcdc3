pn_add_test(test_vpl)
pn_add_test(test_lightcuts)
pn_add_test(test_illumcut)
