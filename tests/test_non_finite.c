/* test_non_finite.c — an eye sample whose value comes out NaN or infinite is counted as 0 by
 * every integrator (so that one bad sample does not poison the pixel), which also hides it: a
 * 0/0 in ias's BVH cut once blackened 45% of a scene's pixels unnoticed. The count now reaches
 * the statistic non_finite_samples and a warning. Here an emitter of radiance 3e38 (finite, but
 * its products overflow float) makes ias's samples infinite: the statistic counts them, the
 * warning names the integrator, and the image holds only finite values; the same scene with
 * radiance 1 counts none. */
#include "harness.h"

#include "penumbra/penumbra.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static const char *scene_text(double L) {
    static char text[1024];
    snprintf(text, sizeof text,
             "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n"
             "Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\nWorldBegin\n"
             "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [%g %g %g]\n  Translate 0 0 2\n"
             "  Shape \"bilinearmesh\" \"point3 P\" [-0.3 -0.3 0  0.3 -0.3 0  -0.3 0.3 0  0.3 0.3 0]\nAttributeEnd\n"
             "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
             "Shape \"bilinearmesh\" \"point3 P\" [-3 -3 -1  3 -3 -1  -3 3 -1  3 3 -1]\n",
             L, L, L);
    return text;
}

typedef struct warnings {
    int non_finite;
    char last[512];
} warnings;

static void on_log(void *user, pn_log_level level, const char *message) {
    warnings *w = user;
    if (level == PN_LOG_WARNING && strstr(message, "NaN or infinite") && strstr(message, "ias")) {
        w->non_finite++;
        snprintf(w->last, sizeof w->last, "%s", message);
    }
}

/* Renders the scene with radiance L by ias; returns non_finite_samples (-1 on failure) and
 * whether every pixel of the image is finite. */
static double render_count(double L, const char *name, warnings *w, int *all_finite) {
    const char *path = pn_test_write_file(tmpdir, name, scene_text(L));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, on_log, w);
    pn_scene scene = NULL;
    double count = -1.0;
    *all_finite = 0;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    if (scene) {
        pn_render_settings s = {0};
        s.integrator = PN_INTEGRATOR_IAS;
        s.threshold = 0.01;
        s.seed = 1;
        s.threads = 1;
        pn_image img = NULL;
        pn_stats stats = pn_stats_new();
        pn_status st = pn_render(ctx, scene, &s, &img, stats);
        CHECK_MSG(st == PN_OK, "render: %s", pn_context_error_message(ctx));
        if (st == PN_OK) {
            CHECK(pn_stats_get(stats, "non_finite_samples", &count) == 1);
            const float *a = pn_image_layer_data(img, 0);
            *all_finite = 1;
            for (int i = 0; i < 3 * pn_image_width(img) * pn_image_height(img); i++)
                if (!isfinite(a[i])) *all_finite = 0;
        }
        pn_image_free(img);
        pn_stats_free(stats);
        pn_scene_free(scene);
    }
    pn_context_free(ctx);
    if (path) unlink(path);
    return count;
}

static void test_non_finite_samples_counted_and_warned(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_non_finite_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
    warnings hot = {0}, plain = {0};
    int finite_hot = 0, finite_plain = 0;
    double n_hot = render_count(3e38, "hot.pbrt", &hot, &finite_hot);
    double n_plain = render_count(1.0, "plain.pbrt", &plain, &finite_plain);
    fprintf(stderr, "  radiance 3e38: %g non-finite samples (%s); radiance 1: %g\n", n_hot, hot.last, n_plain);
    CHECK_MSG(n_hot > 0.0, "the overflowing scene counted %g non-finite samples", n_hot);
    CHECK_MSG(hot.non_finite == 1, "%d warnings about them", hot.non_finite);
    CHECK(finite_hot);
    CHECK_MSG(n_plain == 0.0, "the plain scene counted %g", n_plain);
    CHECK(plain.non_finite == 0);
    CHECK(finite_plain);
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(test_non_finite_samples_counted_and_warned))
