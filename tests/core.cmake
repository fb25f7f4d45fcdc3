# Core utilities: hashing, random numbers, thread pool, the warning path.
pn_add_test(test_core)
pn_add_test(test_warn)
