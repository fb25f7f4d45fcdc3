# Equal-energy partition of environment maps into light-cluster regions (IAS §4.3, §5.1).
pn_add_test(test_env_regions)
