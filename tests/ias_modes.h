/* ias_modes.h — renders for the ias tests that compare one option's modes on the same shadow rays
 * (test_ias_ratio, test_ias_mis, test_ias_guide; header only, after harness.h). */
#ifndef PN_TEST_IAS_MODES_H
#define PN_TEST_IAS_MODES_H

#include "penumbra/penumbra.h"
#include "render_fields.h"

#include <stdio.h>

/* Renders `scene` with `threads` threads. `opts` (name, value pairs ending in NULL) are set when given,
 * and then the threshold is 1e-7, so that no pixel stops before the passes the options ask for
 * and every mode takes the same shadow rays; without them the integrator's defaults apply. NULL
 * when the render fails (the context's message is printed). */
static inline pn_image pn_test_render_modes(pn_context ctx, pn_scene scene, pn_integrator_kind kind, uint32_t spp,
                                            uint64_t seed, int threads, const char *const *opts) {
    pn_render_settings s = PN_RENDER_SETTINGS_INIT;
    pn_options o = pn_options_new();
    s.options = o;
    if (opts) {
        for (int i = 0; opts[i]; i += 2) CHECK(pn_options_set(ctx, o, opts[i], opts[i + 1]) == PN_OK);
        s.threshold = 1e-7;
    }
    s.integrator = kind;
    s.spp = spp;
    s.seed = seed;
    s.threads = threads;
    pn_image img = NULL;
    pn_status st = pn_test_render(ctx, scene, &s, &img, NULL);
    pn_options_free(o);
    if (st != PN_OK) fprintf(stderr, "  render failed: %s\n", pn_context_error_message(ctx));
    return st == PN_OK ? img : NULL;
}

/* Rec. 709 luminance of pixel i of an RGB layer. */
static inline double pn_test_lum_at(const float *a, int i) {
    return 0.2126 * (double)a[3 * i] + 0.7152 * (double)a[3 * i + 1] + 0.0722 * (double)a[3 * i + 2];
}

#endif
