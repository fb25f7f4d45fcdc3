# Core utilities: hashing, random numbers, thread pool, the warning path, the binary heap.
pn_add_test(test_core)
pn_add_test(test_warn)
pn_add_test(test_heap)
