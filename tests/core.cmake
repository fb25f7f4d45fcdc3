# Core utilities: hashing, random numbers, thread pool.
pn_add_test(test_core)
