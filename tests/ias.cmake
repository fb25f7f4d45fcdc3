pn_add_test(test_ias)
pn_add_test(test_ias_default)
pn_add_test(test_ias_converge)
pn_add_test(test_ias_speed)
