pn_add_test(test_cluster)
pn_add_test(test_cluster_share)
