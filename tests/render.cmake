pn_add_test(test_render)

# The batch's eye hits (render/batch.h): traced by the driver in advance and through the batch's
# callback; reference's contract with them (count, order, determinism).
pn_add_test(test_batch)
pn_add_test(test_non_finite)
