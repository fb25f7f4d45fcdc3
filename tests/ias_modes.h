/* ias_modes.h — renders for the ias tests that compare one option's modes on the same shadow rays
 * (test_ias_ratio, test_ias_mis, test_ias_guide; header only, after harness.h). */
#ifndef PN_TEST_IAS_MODES_H
#define PN_TEST_IAS_MODES_H

#include "penumbra/penumbra.h"
#include "render_fields.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>

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

/* Over `seeds` renders of `opts` (pn_test_render_modes: ias, one thread, seeds seed0, seed0 + 1,
 * ...): each image's luminance summed over the pixels where `mask` holds (all with NULL) over
 * ref_sum, into per_seed[k] when per_seed is given, their mean *mean and its standard error *sd;
 * and per pixel the relative variance of one render, the seeds' sample variance over
 * (ref^2 + 0.01), into rv (np values). False when a render or an allocation failed. */
static inline bool pn_test_seed_spread(pn_context ctx, pn_scene scene, const char *const *opts, uint64_t seed0,
                                       int seeds, const float *ref, const bool *mask, int np, double ref_sum,
                                       double *per_seed, double *mean, double *sd, double *rv) {
    double m1 = 0.0, m2 = 0.0;
    double *ps = calloc((size_t)np, sizeof *ps), *ps2 = calloc((size_t)np, sizeof *ps2);
    bool ok = ps && ps2;
    CHECK(ok);
    for (int k = 0; k < seeds && ok; k++) {
        pn_image img = pn_test_render_modes(ctx, scene, PN_INTEGRATOR_IAS, 0, seed0 + (uint64_t)k, 1, opts);
        CHECK(img != NULL);
        if (!img) {
            ok = false;
            break;
        }
        const float *b = pn_image_layer_data(img, 0);
        double sum = 0.0;
        for (int i = 0; i < np; i++) {
            double y = pn_test_lum_at(b, i);
            if (!mask || mask[i]) sum += y;
            ps[i] += y;
            ps2[i] += y * y;
        }
        if (per_seed) per_seed[k] = sum / ref_sum;
        m1 += sum / ref_sum / seeds;
        m2 += (sum / ref_sum) * (sum / ref_sum) / seeds;
        pn_image_free(img);
    }
    for (int i = 0; ok && i < np; i++) {
        double mu = ps[i] / seeds, ya = pn_test_lum_at(ref, i);
        rv[i] = fmax(0.0, ps2[i] - seeds * mu * mu) / (seeds - 1.0) / (ya * ya + 0.01);
    }
    free(ps);
    free(ps2);
    *mean = m1;
    *sd = sqrt(fmax(0.0, m2 - m1 * m1) / (seeds - 1.0));
    return ok;
}

#endif
