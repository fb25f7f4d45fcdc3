# pbrt-v4 light BVH (the reference integrator's second light sampler): structure, probabilities,
# support, and agreement with the default sampler on a small scene.
pn_add_test(test_light_bvh)
