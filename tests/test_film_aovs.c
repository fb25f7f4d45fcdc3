/* test_film_aovs.c — film's one AOV table and its image assembly: every PN_AOV_* bit has exactly
 * one selectable layer, names are unique, the public name list is the table's, every method's
 * declared AOVs exist, and pn_film_assemble writes each requested layer, in table order, with
 * the value of the estimate field the table names (closed forms on synthetic estimates). */
#include "harness.h"

#include "film/aovs.h"
#include "io/image.h"
#include "spectral/cie.h"

#include <stdint.h>

#define ALL_BITS ((PN_AOV_MELANOPIC_EDI << 1) - 1u) /* bits 0..20 of the public enum */

static void test_every_bit_has_one_selectable_layer(void) {
    uint32_t seen = 0;
    for (int i = 0; i < pn_aov_layer_count(); i++) {
        const pn_aov_layer *l = pn_aov_layer_at(i);
        CHECK(l != NULL);
        CHECK(l->channels == 1 || l->channels == 3);
        CHECK((l->bit & (l->bit - 1)) == 0 && l->bit != 0); /* one bit */
        CHECK(l->source != PN_AOV_FROM_VEC3 || l->channels == 3);
        if (l->derived) {
            CHECK(pn_aov_layer_of(l->bit) != NULL); /* written beside a selectable layer */
            continue;
        }
        CHECK_MSG((seen & l->bit) == 0, "bit of %s selectable twice", l->name);
        seen |= l->bit;
        CHECK(pn_aov_layer_of(l->bit) == l);
        for (int j = 0; j < i; j++) CHECK(strcmp(pn_aov_layer_at(j)->name, l->name) != 0);
    }
    CHECK(seen == ALL_BITS);
    CHECK(pn_aov_layer_at(-1) == NULL && pn_aov_layer_at(pn_aov_layer_count()) == NULL);
    CHECK(pn_aov_layer_of(1u << 30) == NULL);
}

static void test_public_names_are_the_table(void) {
    int n = 0;
    for (int i = 0; i < pn_aov_layer_count(); i++) n += !pn_aov_layer_at(i)->derived;
    CHECK(pn_aov_count() == n);
    CHECK(n == 21);
    for (int i = 0; i < n; i++) {
        uint32_t bit = 0;
        const char *name = pn_aov_name(i, &bit);
        CHECK(name != NULL);
        const pn_aov_layer *l = pn_aov_layer_of(bit);
        CHECK(l && strcmp(l->name, name) == 0);
    }
    CHECK(pn_aov_name(n, NULL) == NULL && pn_aov_name(-1, NULL) == NULL);
    /* The common layers: the first six names, luminance and XYZ (every integrator's radiance). */
    uint32_t common = 0, bit;
    for (int i = 0; i < 6; i++) {
        pn_aov_name(i, &bit);
        common |= bit;
    }
    CHECK((common | PN_AOV_LUMINANCE | PN_AOV_XYZ) == PN_AOV_COMMON);
}

static void test_method_aovs_exist(void) {
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        CHECK(mi != NULL);
        CHECK_MSG((mi->aovs & ~ALL_BITS) == 0, "%s declares an AOV the table lacks", mi->name);
        for (uint32_t b = 1; b && b <= ALL_BITS; b <<= 1)
            if (mi->aovs & b) CHECK(pn_aov_layer_of(b) != NULL);
    }
}

/* Estimates with distinct values per pixel and field, so that a layer filled from the wrong
 * field or pixel is seen. */
static void fill_estimates(pn_pixel_estimate *px, int n) {
    memset(px, 0, (size_t)n * sizeof *px);
    for (int i = 0; i < n; i++) {
        float f = (float)i;
        px[i].radiance = v3(f + 0.5f, f + 0.25f, f + 0.125f);
        px[i].shadow_rays = 10u * (uint32_t)i + 1u;
        px[i].eye_rays = 20u * (uint32_t)i + 2u;
        px[i].relative_variance = 0.01f * f;
        px[i].depth = 3.0f + f;
        px[i].normal = v3(0, 1, -f);
        px[i].albedo = v3(0.1f, 0.2f, 0.3f * f);
        px[i].passes = 5u + (uint32_t)i;
        px[i].aa_regions = 7u + (uint32_t)i;
        px[i].clusters = 1.5f + f;
        px[i].visible_fraction = 0.125f * f;
        px[i].bound_evaluations = 99.0f + 900.0f * f; /* log10(1 + 99) = 2, log10(1000) = 3 */
        px[i].cut_size = 4.0f + f;
        px[i].phase1 = v3(f, 2 * f, 3 * f);
        px[i].gradient = v3(-f, 0.5f, f);
        px[i].illuminance = 250.0f + f;
        px[i].melanopic_edi = 125.0f + f;
    }
}

static int layer_index(pn_image img, const char *name) {
    for (int i = 0; i < pn_image_layer_count(img); i++)
        if (strcmp(pn_image_layer_name(img, i), name) == 0) return i;
    return -1;
}

static void test_assemble_all(void) {
    enum { W = 3, H = 2, N = W * H };
    pn_pixel_estimate px[N];
    fill_estimates(px, N);
    pn_image img = NULL;
    CHECK(pn_film_assemble(px, W, H, ALL_BITS, &img) == PN_OK);
    if (!img) return;
    /* Every layer but the driver's, in table order, after the beauty. */
    int expect = 1;
    for (int i = 0; i < pn_aov_layer_count(); i++) {
        const pn_aov_layer *l = pn_aov_layer_at(i);
        if (l->source == PN_AOV_FROM_DRIVER) {
            CHECK(layer_index(img, l->name) < 0);
            continue;
        }
        CHECK_MSG(layer_index(img, l->name) == expect, "%s at %d", l->name, layer_index(img, l->name));
        CHECK(pn_image_layer_channels(img, expect) == l->channels);
        expect++;
    }
    CHECK(pn_image_layer_count(img) == expect);
    const float *b = pn_image_layer_data(img, 0);
    const float *sr = pn_image_layer_data(img, layer_index(img, "shadow_rays"));
    const float *nm = pn_image_layer_data(img, layer_index(img, "normal"));
    const float *lb = pn_image_layer_data(img, layer_index(img, "log10_bound_evaluations"));
    const float *bd = pn_image_layer_data(img, layer_index(img, "bound_evaluations"));
    const float *gr = pn_image_layer_data(img, layer_index(img, "gradient"));
    const float *vf = pn_image_layer_data(img, layer_index(img, "visible_fraction"));
    const float *pa = pn_image_layer_data(img, layer_index(img, "passes"));
    const float *lx = pn_image_layer_data(img, layer_index(img, "illuminance"));
    const float *lm = pn_image_layer_data(img, layer_index(img, "luminance"));
    const float *xyz = pn_image_layer_data(img, layer_index(img, "XYZ"));
    const float *mel = pn_image_layer_data(img, layer_index(img, "melanopic_edi"));
    for (int i = 0; i < N; i++) {
        CHECK(b[3 * i] == px[i].radiance.x && b[3 * i + 2] == px[i].radiance.z);
        CHECK(sr[i] == (float)(10 * i + 1));
        CHECK(nm[3 * i + 1] == 1.0f && nm[3 * i + 2] == -(float)i);
        CHECK(bd[i] == 99.0f + 900.0f * (float)i);
        CHECK(vf[i] == 0.125f * (float)i);
        CHECK(pa[i] == (float)(5 + i));
        CHECK(gr[3 * i] == -(float)i && gr[3 * i + 1] == 0.5f);
        CHECK(lx[i] == 250.0f + (float)i);
        /* the Rec. 709 Y of the radiance (docs/units.md) */
        double y = 0.2126 * (i + 0.5) + 0.7152 * (i + 0.25) + 0.0722 * (i + 0.125);
        CHECK_NEAR(lm[i], y, 1e-4 * y);
        /* XYZ: the IEC 61966-2-1 matrix of the radiance; Y within 4e-4 of the luminance */
        const double rgb[3] = {i + 0.5, i + 0.25, i + 0.125};
        double e[3];
        pn_linear_srgb_to_xyz(rgb, e);
        for (int k = 0; k < 3; k++) CHECK(xyz[3 * i + k] == (float)e[k]);
        CHECK_NEAR(xyz[3 * i + 1], y, 4e-4 * y);
        CHECK(mel[i] == 125.0f + (float)i);
    }
    CHECK_NEAR(lb[0], 2.0, 1e-6);
    CHECK_NEAR(lb[1], 3.0, 1e-6);
    pn_image_free(img);
}

static void test_assemble_subset(void) {
    enum { N = 4 };
    pn_pixel_estimate px[N];
    fill_estimates(px, N);
    pn_image img = NULL;
    /* Requested out of table order: the image still follows the table. */
    CHECK(pn_film_assemble(px, 2, 2, PN_AOV_GRADIENT | PN_AOV_EYE_RAYS | PN_AOV_SAMPLING_PATTERN, &img) == PN_OK);
    if (!img) return;
    CHECK(pn_image_layer_count(img) == 3);
    CHECK(strcmp(pn_image_layer_name(img, 1), "eye_rays") == 0);
    CHECK(strcmp(pn_image_layer_name(img, 2), "gradient") == 0);
    const float *e = pn_image_layer_data(img, 1);
    for (int i = 0; i < N; i++) CHECK(e[i] == (float)(20 * i + 2));
    pn_image_free(img);
    /* No AOVs: the beauty alone. A driver's own layer comes from pn_film_add_aov. */
    CHECK(pn_film_assemble(px, 2, 2, 0, &img) == PN_OK);
    if (!img) return;
    CHECK(pn_image_layer_count(img) == 1);
    float *map = pn_film_add_aov(img, PN_AOV_BLOCK_MAP);
    CHECK(map != NULL && map[0] == 0.0f);
    CHECK(pn_image_layer_count(img) == 2 && strcmp(pn_image_layer_name(img, 1), "block_map") == 0);
    CHECK(pn_film_add_aov(img, 1u << 30) == NULL);
    pn_image_free(img);
    /* A bad size fails without an image. */
    img = (pn_image)1;
    CHECK(pn_film_assemble(px, 0, 2, 0, &img) == PN_ERROR_OUT_OF_MEMORY && img == NULL);
}

PN_TESTS(TEST(test_every_bit_has_one_selectable_layer), TEST(test_public_names_are_the_table),
         TEST(test_method_aovs_exist), TEST(test_assemble_all), TEST(test_assemble_subset))
