/* test_ias_scale.c — the trees cut's statistics at many emitters (issue 15, light count; ias.c,
 * sparse_stats): on a floor under a ceiling of N small emitting triangles, written here,
 *  - the hash-table statistics give the dense arrays' images bit for bit (N = 1,000 and 30,000,
 *    default and paper variants);
 *  - their work per shadow ray (entries aggregated, set and cleared, pn_ias_stats_work) grows by
 *    less than 3x from N = 1,000 to 30,000 (log N), where the dense arrays' grows with N (checked too, so
 *    that the measure is known to see the difference: with the hash tables switched off, by
 *    pn_ias_set_dense_limit(INT_MAX), the first check fails). */
#include "harness.h"
#include "render_fields.h"

#include "integrators/ias_speed.h"
#include "penumbra/penumbra.h"

#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[512];

/* A 10 x 10 floor at y = 0 and n triangles facing down at y = 3 on a jittered grid. */
static char *scene_text(int n) {
    size_t cap = 4096 + (size_t)n * 160;
    char *t = malloc(cap);
    size_t k = (size_t)snprintf(t, cap,
                                "Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n"
                                "LookAt 0 2 6  0 0 0  0 1 0\n"
                                "Camera \"perspective\" \"float fov\" [ 50 ]\n"
                                "WorldBegin\n"
                                "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
                                "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n"
                                "  \"point3 P\" [ -5 0 -5  5 0 -5  5 0 5  -5 0 5 ]\n"
                                "AttributeBegin\n"
                                "AreaLightSource \"diffuse\" \"rgb L\" [ %g %g %g ]\n"
                                "Shape \"trianglemesh\" \"point3 P\" [\n",
                                2000.0 / n, 2000.0 / n, 2000.0 / n);
    int side = 1;
    while (side * side < n) side++;
    const double cell = 8.0 / side;
    for (int i = 0; i < n; i++) {
        double x = -4.0 + cell * (i % side + 0.5 + 0.3 * sin(1.7 * i)), z = -4.0 + cell * (i / side + 0.5);
        double s = 0.3 * cell;
        k += (size_t)snprintf(t + k, cap - k, "%.5f 3 %.5f %.5f 3 %.5f %.5f 3 %.5f\n", x, z, x + s, z, x, z + s);
    }
    k += (size_t)snprintf(t + k, cap - k, "] \"integer indices\" [\n");
    for (int i = 0; i < n; i++) k += (size_t)snprintf(t + k, cap - k, "%d %d %d\n", 3 * i, 3 * i + 1, 3 * i + 2);
    snprintf(t + k, cap - k, "]\nAttributeEnd\n");
    return t;
}

static pn_image render(pn_context ctx, pn_scene scene, const char *variant, pn_render_stats *stats) {
    pn_render_settings s = PN_RENDER_SETTINGS_INIT;
    pn_options o = pn_options_new();
    s.options = o;
    CHECK(pn_options_set(ctx, o, "ias-variant", variant) == PN_OK);
    s.integrator = PN_INTEGRATOR_IAS;
    s.threshold = 0.05;
    s.threads = 1;
    pn_image img = NULL;
    pn_status st = pn_test_render(ctx, scene, &s, &img, stats);
    pn_options_free(o);
    if (st != PN_OK) fprintf(stderr, "  render failed: %s\n", pn_context_error_message(ctx));
    return st == PN_OK ? img : NULL;
}

static bool same_pixels(pn_image a, pn_image b) {
    if (!a || !b || pn_image_width(a) != pn_image_width(b) || pn_image_height(a) != pn_image_height(b)) return false;
    size_t n = (size_t)pn_image_width(a) * (size_t)pn_image_height(a) * 3;
    return memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(b, 0), n * sizeof(float)) == 0;
}

/* Statistics work per shadow ray of a default-variant render with the given dense limit. */
static double work_per_ray(pn_context ctx, pn_scene scene, int limit, pn_image *img) {
    pn_ias_set_dense_limit(limit);
    pn_render_stats st;
    uint64_t before = pn_ias_stats_work();
    *img = render(ctx, scene, "default", &st);
    uint64_t work = pn_ias_stats_work() - before;
    pn_ias_set_dense_limit(0);
    return st.shadow_rays ? (double)work / (double)st.shadow_rays : 0.0;
}

static void test_sparse_statistics(void) {
    const int counts[2] = {1000, 30000};
    double sparse[2], dense[2];
    for (int c = 0; c < 2; c++) {
        pn_context ctx = pn_context_new();
        char name[64];
        snprintf(name, sizeof name, "scale-%d.pbrt", counts[c]);
        char *text = scene_text(counts[c]);
        const char *path = pn_test_write_file(tmpdir, name, text);
        free(text);
        pn_scene scene = NULL;
        CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
        if (!scene) {
            pn_context_free(ctx);
            continue;
        }
        pn_image a, b;
        sparse[c] = work_per_ray(ctx, scene, 1, &a);
        dense[c] = work_per_ray(ctx, scene, INT_MAX, &b);
        CHECK_MSG(same_pixels(a, b), "%d emitters: hash-table and dense statistics differ", counts[c]);
        pn_image_free(a);
        pn_image_free(b);
        /* The paper variant takes the same path. */
        pn_ias_set_dense_limit(1);
        a = render(ctx, scene, "paper", NULL);
        pn_ias_set_dense_limit(INT_MAX);
        b = render(ctx, scene, "paper", NULL);
        pn_ias_set_dense_limit(0);
        CHECK_MSG(same_pixels(a, b), "%d emitters, paper variant: hash-table and dense statistics differ", counts[c]);
        pn_image_free(a);
        pn_image_free(b);
        pn_scene_free(scene);
        pn_context_free(ctx);
    }
    printf("  statistics work per shadow ray: hash tables %.1f -> %.1f, dense %.1f -> %.1f\n", sparse[0], sparse[1],
           dense[0], dense[1]);
    /* 30x the emitters: the depth below the cut grows by log2(30) ~ 5 levels (measured 2.0 -> 3.9
     * per ray), the dense arrays by 30x (5.1 -> 69). */
    CHECK_MSG(sparse[1] < 3.0 * sparse[0], "hash tables: %.1f -> %.1f", sparse[0], sparse[1]);
    CHECK_MSG(dense[1] > 8.0 * dense[0], "dense: %.1f -> %.1f", dense[0], dense[1]);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_ias_scale_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
    pn_test_remove_at_end(tmpdir);
}

PN_TESTS(TEST(test_setup), TEST(test_sparse_statistics))
