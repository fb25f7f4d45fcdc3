/* test_render.c — end-to-end renders through the public API: closed-form radiance of a diffuse
 * plane under a rectangle light, bit-identical images for 1 and 2 threads, crop windows that
 * reproduce the same pixels as the full image. */
#include "harness.h"

#include "penumbra/penumbra.h"

#include <unistd.h>

static char tmpdir[256];

static const char *write_scene(const char *name, const char *text) {
    return pn_test_write_file(tmpdir, name, text);
}

/* A 10 x 10 diffuse floor (reflectance 0.5) at z = 0 seen from the side (so the light does not
 * hide the centre), lit by a 1 x 1 square
 * light of radiance 3 at height 1 facing down. */
static const char *plane_scene =
    "LookAt 3 0 0.5  0 0 0  0 0 1\n"
    "Camera \"perspective\" \"float fov\" [ 5 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n"
    "WorldBegin\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ]\n"
    "   \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "AttributeBegin\n"
    "  AreaLightSource \"diffuse\" \"rgb L\" [ 3 3 3 ]\n"
    "  Shape \"trianglemesh\" \"point3 P\" [ -0.5 -0.5 1  -0.5 0.5 1  0.5 0.5 1  0.5 -0.5 1 ]\n"
    "     \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "AttributeEnd\n";

static double corner_ff(double a, double b, double h) {
    double A = a / h, B = b / h, sa = sqrt(1 + A * A), sb = sqrt(1 + B * B);
    return (A / sa * atan(B / sa) + B / sb * atan(A / sb)) / (2.0 * M_PI);
}

static void test_plane_under_rectangle_light(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = NULL;
    const char *path = write_scene("plane.pbrt", plane_scene);
    pn_status st = pn_scene_load(ctx, path, &scene);
    CHECK_MSG(st == PN_OK, "%s", pn_context_error_message(ctx));
    if (st != PN_OK) {
        pn_context_free(ctx);
        return;
    }
    pn_scene_info info;
    pn_scene_get_info(scene, &info);
    CHECK(info.lights_area_rectangle == 1);
    pn_render_settings s = {0};
    s.spp = 64;
    s.seed = 1;
    s.crop[0] = 15.0f / 32;
    s.crop[1] = 17.0f / 32;
    s.crop[2] = 15.0f / 32;
    s.crop[3] = 17.0f / 32;
    s.has_crop = 1;
    pn_image img = NULL;
    st = pn_render(ctx, scene, &s, &img, NULL);
    CHECK(st == PN_OK);
    if (img) {
        /* The centre pixels see points within ~0.05 of the axis: radiance = rho/pi * E with
         * E = pi * L * F, F of the centred square = 4 corner rectangles of 0.5 x 0.5. */
        double expected = 0.5 * 3.0 * 4.0 * corner_ff(0.5, 0.5, 1.0);
        const float *px = pn_image_layer_data(img, 0);
        double mean = 0;
        for (int i = 0; i < 4; i++) mean += (double)px[3 * i + 1];
        mean /= 4;
        CHECK_NEAR(mean, expected, 0.01 * expected);
        pn_image_free(img);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static pn_image render_with_threads(pn_scene scene, pn_context ctx, int threads, int adaptive, const float *crop) {
    pn_render_settings s = {0};
    if (adaptive)
        s.threshold = 0.02;
    else
        s.spp = 4;
    s.seed = 42;
    s.threads = threads;
    pn_options o = pn_options_new();
    s.options = o;
    pn_options_set_int(ctx, o, "shadow-rays", 2);
    if (crop) {
        s.has_crop = 1;
        memcpy(s.crop, crop, sizeof s.crop);
    }
    pn_image img = NULL;
    pn_render(ctx, scene, &s, &img, NULL);
    pn_options_free(o);
    return img;
}

static void test_thread_count_determinism(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = NULL;
    const char *path = write_scene("plane2.pbrt", plane_scene);
    if (pn_scene_load(ctx, path, &scene) != PN_OK) {
        CHECK_MSG(0, "%s", pn_context_error_message(ctx));
        pn_context_free(ctx);
        return;
    }
    for (int adaptive = 0; adaptive < 2; adaptive++) {
        pn_image a = render_with_threads(scene, ctx, 1, adaptive, NULL);
        pn_image b = render_with_threads(scene, ctx, 2, adaptive, NULL);
        pn_image c = render_with_threads(scene, ctx, 3, adaptive, NULL);
        CHECK(a && b && c);
        if (a && b && c) {
            size_t n = 3 * 32 * 32 * sizeof(float);
            CHECK(memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(b, 0), n) == 0);
            CHECK(memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(c, 0), n) == 0);
        }
        /* A crop reproduces the same pixels as the full image. */
        float crop[4] = {0.25f, 0.75f, 0.5f, 1.0f};
        pn_image d = render_with_threads(scene, ctx, 2, adaptive, crop);
        CHECK(d != NULL);
        if (a && d) {
            CHECK(pn_image_width(d) == 16 && pn_image_height(d) == 16);
            const float *full = pn_image_layer_data(a, 0), *part = pn_image_layer_data(d, 0);
            int mismatches = 0;
            for (int y = 0; y < 16; y++)
                for (int x = 0; x < 16; x++)
                    for (int c2 = 0; c2 < 3; c2++)
                        if (full[3 * ((y + 16) * 32 + (x + 8)) + c2] != part[3 * (y * 16 + x) + c2]) mismatches++;
            CHECK_MSG(mismatches == 0, "%d values differ", mismatches);
        }
        pn_image_free(a);
        pn_image_free(b);
        pn_image_free(c);
        pn_image_free(d);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_render_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        fprintf(stderr, "mkdtemp failed\n");
        exit(1);
    }
    pn_test_remove_at_end(tmpdir);
}

static void test_setup(void) {
    setup();
}

PN_TESTS(TEST(test_setup), TEST(test_plane_under_rectangle_light), TEST(test_thread_count_determinism))
