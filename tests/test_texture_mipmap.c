/* test_texture_mipmap.c — image textures read through pbrt-v4's pyramid (scene/mipmap.c) and
 * the camera rays' texture footprint (render/camera.c, accel pn_hit_uv_footprint):
 *  1. the pyramid: a non-power-of-two image resized up by pbrt's normalised 4-tap windowed sinc
 *     (one texel against the weights computed here), a constant kept exactly, box levels, the
 *     top texel the mean of a power-of-two image;
 *  2. lookups: level = levels - 1 + log2(2 max |d|) picks the level (bilinear), trilinear blends
 *     two levels, a very wide footprint gives the top texel, a zero one level 0;
 *  3. a render: a checkerboard of two-texel cells, 2.68 texels per pixel, at 1 spp (camera
 *     differentials scaled by 1): every pixel's albedo is the pyramid's 0.5 (level 2.42: all its
 *     texels are 0.5); at 4 spp (scale 1/2, level 1.42) 0.58 of level 1 (a one-texel checker)
 *     and 0.42 of 0.5; at 16 spp (level 0.42) level 0 alone, 0 to 1. Without pyramids the 1 spp
 *     albedo is the checker's 0 or 1 bilinearly blended. */
#include "harness.h"

#include "io/image.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static char tmpdir[256];

static double wsinc(double x) {
    if (fabs(x) > 2.0) return 0.0;
    double a = M_PI * x, b = M_PI * x / 2.0;
    return (fabs(a) < 1e-9 ? 1.0 : sin(a) / a) * (fabs(b) < 1e-9 ? 1.0 : sin(b) / b);
}

static void test_pyramid(void) {
    pn_err err;
    pn_err_init(&err);
    /* A 3 x 1 row (0.1, 0.5, 0.9): resized to 4 x 1, repeat wrap. */
    float row[9] = {0.1f, 0.1f, 0.1f, 0.5f, 0.5f, 0.5f, 0.9f, 0.9f, 0.9f};
    pn_mipmap m;
    CHECK(pn_mipmap_build(row, 3, 1, PN_WRAP_REPEAT, &m, &err) == PN_OK);
    CHECK(m.levels == 3 && m.level[0].width == 4 && m.level[0].height == 1);
    const double v[3] = {0.1, 0.5, 0.9};
    for (int i = 0; i < 4; i++) {
        double centre = (i + 0.5) * 3.0 / 4.0, w[4], sum = 0.0, expect = 0.0;
        int first = (int)floor(centre - 2.0 + 0.5);
        for (int j = 0; j < 4; j++) sum += w[j] = wsinc(first + j + 0.5 - centre);
        for (int j = 0; j < 4; j++) expect += w[j] / sum * v[((first + j) % 3 + 3) % 3];
        if (expect < 0.0) expect = 0.0;
        CHECK_NEAR((double)m.level[0].rgb[3 * i], expect, 1e-6);
    }
    /* Level 1 the pair averages, the top their mean. */
    CHECK_NEAR(m.level[1].rgb[0], 0.5f * (m.level[0].rgb[0] + m.level[0].rgb[3]), 1e-7);
    CHECK_NEAR(m.level[2].rgb[0],
               0.25f * (m.level[0].rgb[0] + m.level[0].rgb[3] + m.level[0].rgb[6] + m.level[0].rgb[9]), 1e-6);
    pn_mipmap_free(&m);

    /* A constant 5 x 3 image stays constant at every level (normalised weights). */
    float c[45];
    for (int i = 0; i < 45; i++) c[i] = 0.3f;
    CHECK(pn_mipmap_build(c, 5, 3, PN_WRAP_CLAMP, &m, &err) == PN_OK);
    CHECK(m.levels == 4 && m.level[0].width == 8 && m.level[0].height == 4);
    for (int l = 0; l < m.levels; l++)
        for (int i = 0; i < 3 * m.level[l].width * m.level[l].height; i++) CHECK_NEAR(m.level[l].rgb[i], 0.3, 1e-6);
    CHECK(m.level[3].width == 1 && m.level[3].height == 1);
    pn_mipmap_free(&m);

    /* A power-of-two image is level 0 as it is; its top texel is its mean. */
    float p[48];
    double mean = 0.0;
    for (int i = 0; i < 16; i++) {
        p[3 * i] = p[3 * i + 1] = p[3 * i + 2] = (float)(i * i) / 225.0f;
        mean += (double)(i * i) / 225.0 / 16.0;
    }
    CHECK(pn_mipmap_build(p, 4, 4, PN_WRAP_REPEAT, &m, &err) == PN_OK);
    CHECK(m.levels == 3 && memcmp(m.level[0].rgb, p, sizeof p) == 0);
    CHECK_NEAR(m.level[2].rgb[1], mean, 1e-6);

    /* Lookups at the centre of texel (1, 1) of level 1 = (0.375, 0.375). */
    const float s = 0.375f, t = 0.375f;
    float zero[4] = {0, 0, 0, 0};
    vec3 l0 = pn_mip_level_bilerp(&m.level[0], s, t, m.wrap), l1 = pn_mip_level_bilerp(&m.level[1], s, t, m.wrap);
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_TRILINEAR, s, t, zero).x, l0.x, 1e-7);
    /* width 2 * 0.25 = 0.5: level 2 + log2(0.5) = 1 exactly. */
    float d1[4] = {0.25f, -0.1f, 0.0f, 0.05f};
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_BILINEAR, s, t, d1).x, l1.x, 1e-7);
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_TRILINEAR, s, t, d1).x, l1.x, 1e-6);
    /* level 1.5: trilinear blends levels 1 and 2 half and half; bilinear stays in level 1. */
    float d15[4] = {0.0f, 0.0f, (float)(0.25 * sqrt(2.0)), 0.0f};
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_TRILINEAR, s, t, d15).x, 0.5 * ((double)l1.x + mean), 1e-6);
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_BILINEAR, s, t, d15).x, l1.x, 1e-7);
    /* Point: the nearest texel of level 1: (0.375 * 2 - 0.5 = 0.25 rounds to 0) texel (0, 0). */
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_POINT, s, t, d15).x, m.level[1].rgb[0], 1e-7);
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_POINT, 0.76f, 0.76f, d15).x, m.level[1].rgb[9], 1e-7);
    /* Trilinear below level 1 reads level 0 only (pbrt-v4: no blend when floor(level) = 0). */
    float d05[4] = {(float)(0.125 * sqrt(2.0)), 0.0f, 0.0f, 0.0f};
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_TRILINEAR, s, t, d05).x, l0.x, 1e-7);
    /* A footprint wider than the image: the top texel. */
    float big[4] = {0.0f, 2.0f, 0.0f, 0.0f};
    CHECK_NEAR(pn_mipmap_lookup(&m, PN_TEXTURE_FILTER_POINT, s, t, big).x, mean, 1e-6);
    pn_mipmap_free(&m);
}

/* A 64 x 64 TGA checkerboard of 2 x 2 texel cells (black and white). */
static bool write_checker(const char *path) {
    FILE *f = fopen(path, "wb");
    if (!f) return false;
    unsigned char h[18] = {0};
    h[2] = 2;
    h[12] = 64;
    h[14] = 64;
    h[16] = 24;
    h[17] = 0x20;
    bool ok = fwrite(h, 1, sizeof h, f) == sizeof h;
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 64; x++) {
            unsigned char v = (x / 2 + y / 2) % 2 ? 255 : 0, px[3] = {v, v, v};
            ok = ok && fwrite(px, 1, 3, f) == 3;
        }
    return fclose(f) == 0 && ok;
}

/* The albedo AOV of a render of the checker quad at spp samples per pixel: its min and max. */
static bool albedo_range(pn_context ctx, pn_scene scene, uint32_t spp, double *lo, double *hi) {
    pn_render_settings s = {0};
    s.integrator = PN_INTEGRATOR_REFERENCE;
    s.spp = spp;
    s.threads = 1;
    s.aovs = PN_AOV_ALBEDO;
    pn_image img = NULL;
    if (pn_render(ctx, scene, &s, &img, NULL) != PN_OK) return false;
    int layer = -1;
    for (int i = 0; i < pn_image_layer_count(img); i++)
        if (pn_image_layer_name(img, i) && strcmp(pn_image_layer_name(img, i), "albedo") == 0) layer = i;
    bool ok = layer >= 0;
    *lo = 1e30;
    *hi = -1e30;
    if (ok) {
        const float *a = pn_image_layer_data(img, layer);
        int n = pn_image_width(img) * pn_image_height(img), ch = pn_image_layer_channels(img, layer);
        for (int i = 0; i < n; i++) {
            double g = a[(size_t)i * (size_t)ch + (ch > 1 ? 1 : 0)];
            *lo = g < *lo ? g : *lo;
            *hi = g > *hi ? g : *hi;
        }
    }
    pn_image_free(img);
    return ok;
}

static void test_camera_footprint(void) {
    pn_context ctx = pn_context_new();
    char tga[512];
    snprintf(tga, sizeof tga, "%s/checker.tga", tmpdir);
    CHECK(write_checker(tga));
    /* 16 x 16 pixels, fov 30 at distance 5: a pixel is 2 * 5 tan(15 deg) / 16 = 0.1675 units; the
     * quad [-2, 2]^2 (all of the view) carries 64 texels over 4 units: 2.68 texels per pixel. */
    const char *text = "LookAt 0 0 5  0 0 0  0 1 0\n"
                       "Camera \"perspective\" \"float fov\" [ 30 ]\n"
                       "Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n"
                       "WorldBegin\n"
                       "LightSource \"distant\" \"point3 from\" [ 0 0 5 ] \"point3 to\" [ 0 0 0 ]\n"
                       "Texture \"c\" \"spectrum\" \"imagemap\" \"string filename\" \"checker.tga\"\n"
                       "    \"string filter\" \"trilinear\"\n"
                       "Material \"diffuse\" \"texture reflectance\" \"c\"\n"
                       "Shape \"trianglemesh\" \"point3 P\" [ -2 -2 0  2 -2 0  2 2 0  -2 2 0 ]\n"
                       "    \"point2 uv\" [ 0 0  1 0  1 1  0 1 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n";
    /* At 1 spp the footprint is d = 2.68 / 64 (du/dx; dv/dy the same), level = 6 + log2(2 d) =
     * 2.42: levels 2 and 3, all 0.5. */
    const char *path = pn_test_write_file(tmpdir, "checker.pbrt", text);
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    double lo, hi;
    if (scene && albedo_range(ctx, scene, 1, &lo, &hi)) {
        printf("1 spp albedo range [%.5f, %.5f]\n", lo, hi);
        CHECK_MSG(lo > 0.499 && hi < 0.501, "1 spp: albedo in [%g, %g], expected 0.5", lo, hi);
    } else
        CHECK(!"render at 1 spp");
    /* 4 spp: scale 1/2, level 1.42: 0.58 of level 1's bilinear value (0..1) + 0.42 * 0.5, so
     * the albedo (of each pixel's first sample) spans more than [0.45, 0.55] but stays within
     * [0.21, 0.79]. */
    if (scene && albedo_range(ctx, scene, 4, &lo, &hi)) {
        printf("4 spp albedo range [%.5f, %.5f]\n", lo, hi);
        CHECK_MSG(lo < 0.45 && hi > 0.55 && lo > 0.205 && hi < 0.795, "4 spp: albedo in [%g, %g]", lo, hi);
    } else
        CHECK(!"render at 4 spp");
    /* 16 spp: scale 1/4, level 0.42, floor 0: level 0 alone (pbrt's trilinear), so beyond. */
    if (scene && albedo_range(ctx, scene, 16, &lo, &hi)) {
        printf("16 spp albedo range [%.5f, %.5f]\n", lo, hi);
        CHECK_MSG(lo < 0.2 && hi > 0.8, "16 spp: albedo in [%g, %g]", lo, hi);
    } else
        CHECK(!"render at 16 spp");
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_texture_mipmap_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        fprintf(stderr, "mkdtemp failed\n");
        exit(1);
    }
    pn_test_remove_at_end(tmpdir);
}

PN_TESTS(TEST(test_setup), TEST(test_pyramid), TEST(test_camera_footprint))
