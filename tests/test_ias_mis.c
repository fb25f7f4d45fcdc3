/* test_ias_mis.c — BSDF sampling (shade/bsdf.h) and ias's MIS of light and BSDF samples
 * (integrators/ias_mis.h, option ias-mis; issue 15):
 *  - pn_bsdf_sample / pn_bsdf_pdf and the glossy lobe's own pair: the density integrates (by
 *    quadrature over the sphere) to the share of samples that succeed, and E[f cos / pdf] over
 *    the samples matches the quadrature of f cos over the hemisphere (the Lambert lobe's closed
 *    form kd exactly), per lobe and mixed, at three view angles and two exponents;
 *  - the light PDF that the BSDF rays are weighed against matches the density of
 *    pn_light_sample_point's own samples (a histogram over directions);
 *  - renders of a 1 x 1 m emitting quad over a coated (glossy, exponent 2220) plane, no occluder,
 *    at fixed passes: with ias-mis on, glossy and off the image's mean over four seeds is the
 *    1024-spp reference's within a bound of the seeds' spread, and MIS lowers the per-pixel
 *    variance across seeds on the highlight's pixels to below half of light sampling's;
 *  - ias-mis glossy on a scene without glossy lobes is the off render bit for bit, and so are
 *    the paper variant's renders with ias-mis set. */
#include "harness.h"
#include "ias_modes.h"
#include "render_fields.h"

#include "core/rng.h"
#include "integrators/ias_mis.h"
#include "penumbra/penumbra.h"
#include "shade/bsdf.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static pn_bsdf make_bsdf(float kd, float ks, float n) {
    pn_bsdf b;
    memset(&b, 0, sizeof b);
    b.kind = PN_MATERIAL_LAMBERT_BLINN;
    b.kd = v3(kd, kd, kd);
    b.ks = v3(ks, ks, ks);
    b.exponent = n;
    b.ng = b.ns = v3(0, 0, 1);
    b.entering = true;
    return b;
}

/* Midpoint quadrature over the sphere in (cos theta, phi): the integral of pdf(wi) and, over the
 * upper hemisphere, of luminance(f(wo, wi)) cos. The grid is fine enough for the exponents
 * below (a lobe of width ~ 1 / sqrt(n) ~ 0.07 rad at n = 200 spans ~ 20 steps of phi). */
static void quadrature(const pn_bsdf *b, vec3 wo, bool glossy_only, double *pdf_integral, double *albedo) {
    const int nt = 2000, np = 2000;
    double sp = 0.0, sf = 0.0;
    const double dmu = 2.0 / nt, dphi = 6.283185307179586 / np;
    for (int i = 0; i < nt; i++) {
        /* cos theta from -1 to 1, denser near the pole where the lobe at normal view sits */
        const double mu = -1.0 + (i + 0.5) * dmu, st = sqrt(fmax(0.0, 1.0 - mu * mu));
        for (int j = 0; j < np; j++) {
            const double phi = (j + 0.5) * dphi;
            const vec3 wi = v3((float)(st * cos(phi)), (float)(st * sin(phi)), (float)mu);
            sp += glossy_only ? (double)pn_bsdf_pdf_glossy(b, wo, wi) : (double)pn_bsdf_pdf(b, wo, wi);
            if (mu > 0.0) sf += (double)v3_luminance(pn_bsdf_eval(b, wo, wi)) * mu;
        }
    }
    *pdf_integral = sp * dmu * dphi;
    *albedo = sf * dmu * dphi;
}

/* E[f cos / pdf] over the sampler's samples (failed samples count 0), its standard error, and
 * the share of samples that succeeded. */
static double sampled_albedo(const pn_bsdf *b, vec3 wo, bool glossy_only, double *se, double *accepted) {
    const int count = 400000;
    pn_rng rng;
    pn_rng_seed(&rng, 3, 9);
    double s = 0.0, s2 = 0.0;
    int ok = 0;
    for (int i = 0; i < count; i++) {
        vec3 wi;
        float pdf;
        const float u1 = pn_rng_float(&rng), u2 = pn_rng_float(&rng), u3 = pn_rng_float(&rng);
        const bool good = glossy_only ? pn_bsdf_sample_glossy(b, wo, u2, u3, &wi, &pdf)
                                      : pn_bsdf_sample(b, wo, u1, u2, u3, &wi, &pdf);
        double y = 0.0;
        if (good) {
            ok++;
            const float p_again = glossy_only ? pn_bsdf_pdf_glossy(b, wo, wi) : pn_bsdf_pdf(b, wo, wi);
            CHECK(fabsf(p_again - pdf) <= 1e-5f * pdf);
            y = (double)v3_luminance(pn_bsdf_eval(b, wo, wi)) * (double)v3_dot(b->ns, wi) / (double)pdf;
        }
        s += y;
        s2 += y * y;
    }
    const double m = s / count;
    *se = sqrt(fmax(0.0, s2 / count - m * m) / count);
    *accepted = (double)ok / count;
    return m;
}

static void test_bsdf_sampling(void) {
    const float views[] = {0.0f, 0.8f, 1.25f}; /* angle of wo from the normal, radians */
    struct {
        float kd, ks, n;
        bool glossy_only;
    } cases[] = {
        {0.6f, 0.0f, 1.0f, false},    /* Lambert alone: closed form kd */
        {0.0f, 0.5f, 10.0f, false},   /* Blinn alone, broad */
        {0.0f, 0.5f, 200.0f, false},  /* Blinn alone, narrow */
        {0.5f, 0.04f, 200.0f, false}, /* coated: mixed, glossy weight 0.07 */
        {0.5f, 0.04f, 200.0f, true},  /* the glossy lobe's own strategy on the same BSDF */
        {0.3f, 0.3f, 10.0f, true},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++)
        for (size_t v = 0; v < sizeof views / sizeof views[0]; v++) {
            const pn_bsdf b = make_bsdf(cases[c].kd, cases[c].ks, cases[c].n);
            const vec3 wo = v3(sinf(views[v]), 0.0f, cosf(views[v]));
            double pint, quad, se, acc;
            quadrature(&b, wo, cases[c].glossy_only, &pint, &quad);
            const double mc = sampled_albedo(&b, wo, cases[c].glossy_only, &se, &acc);
            fprintf(stderr,
                    "  kd %.2f ks %.2f n %4.0f%s view %.2f: integral of pdf %.5f, accepted %.5f; albedo %.5f, "
                    "sampled %.5f +- %.5f\n",
                    (double)cases[c].kd, (double)cases[c].ks, (double)cases[c].n, cases[c].glossy_only ? " glossy" : "",
                    (double)views[v], pint, acc, quad, mc, se);
            /* The density integrates to the probability that a sample is returned (1 unless a
             * half vector faces away from wo or wi falls below the horizon). */
            CHECK_MSG(fabs(pint - acc) < 2e-3 + 4.0 * sqrt(acc * (1.0 - acc) / 400000.0),
                      "case %zu view %zu: integral of pdf %.5f, accepted share %.5f", c, v, pint, acc);
            /* Unbiased: E[f cos / pdf] is the integral of f cos where the sampler reaches. The
             * glossy-only strategy does not reach the diffuse lobe's directions away from the
             * highlight, so its expectation is compared with its own lobe's albedo only. */
            if (cases[c].glossy_only) {
                const pn_bsdf g = make_bsdf(0.0f, cases[c].ks, cases[c].n);
                double pg, qg;
                quadrature(&g, wo, true, &pg, &qg);
                double se_g, acc_g;
                const double mg = sampled_albedo(&g, wo, true, &se_g, &acc_g);
                CHECK_MSG(fabs(mg - qg) < 4.0 * se_g + 2e-3 * qg, "glossy lobe: sampled %.5f, quadrature %.5f", mg, qg);
                /* ...and with the diffuse lobe it only adds: more than the lobe alone. */
                CHECK(mc > mg - 4.0 * se);
            } else {
                CHECK_MSG(fabs(mc - quad) < 4.0 * se + 2e-3 * quad, "case %zu view %zu: sampled %.5f, quadrature %.5f",
                          c, v, mc, quad);
            }
            if (cases[c].ks == 0.0f) {
                CHECK_NEAR(quad, cases[c].kd, 1e-3); /* Lambert: the albedo is kd */
                CHECK(se < 1e-6);                    /* and f cos / pdf = kd for every sample */
            }
        }
    /* No lobe: nothing is sampled; a glossy-free BSDF has no glossy strategy. */
    const pn_bsdf black = make_bsdf(0.0f, 0.0f, 1.0f), matte = make_bsdf(0.5f, 0.0f, 1.0f);
    vec3 wi;
    float pdf;
    CHECK(!pn_bsdf_sample(&black, v3(0, 0, 1), 0.5f, 0.5f, 0.5f, &wi, &pdf));
    CHECK(!pn_bsdf_sample_glossy(&matte, v3(0, 0, 1), 0.5f, 0.5f, &wi, &pdf));
    CHECK(pn_bsdf_pdf_glossy(&matte, v3(0, 0, 1), v3(0, 0, 1)) == 0.0f);
}

/* The density pn_light_pdf_direction gives against pn_light_sample_point's samples: histogram of
 * the sampled directions over a small cone around a probe direction, for a rectangle seen large
 * (solid-angle sampling), the same rectangle far away (area sampling), a triangle, a disk and a
 * sphere. */
static void test_light_pdf(void) {
    pn_light l[5];
    memset(l, 0, sizeof l);
    for (int i = 0; i < 5; i++) l[i].env = l[i].mesh = l[i].prim = -1;
    l[0].kind = PN_LIGHT_RECTANGLE;
    l[0].p = v3(-0.5f, -0.5f, 1.0f);
    l[0].e1 = v3(1.0f, 0.0f, 0.0f);
    l[0].e2 = v3(0.0f, 1.0f, 0.0f);
    l[0].n = v3(0.0f, 0.0f, -1.0f);
    l[0].area = 1.0f;
    l[0].emit = v3(1, 1, 1);
    l[1] = l[0];
    l[1].p = v3(-0.005f, -0.005f, 6.0f);
    l[1].e1 = v3(0.01f, 0.0f, 0.0f);
    l[1].e2 = v3(0.0f, 0.01f, 0.0f);
    l[1].area = 1e-4f;
    l[2] = l[0];
    l[2].kind = PN_LIGHT_TRIANGLE;
    l[2].area = 0.5f;
    l[3] = l[0];
    l[3].kind = PN_LIGHT_DISK;
    l[3].p = v3(0.0f, 0.0f, 1.0f);
    l[3].radius = 0.5f;
    l[3].area = PN_PI * 0.25f;
    l[4].kind = PN_LIGHT_SPHERE;
    l[4].p = v3(0.1f, 0.0f, 1.5f);
    l[4].radius = 0.4f;
    l[4].area = 4.0f * PN_PI * 0.16f;
    l[4].emit = v3(1, 1, 1);
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = l;
    L.count = 5;
    L.scene_radius = 10.0f;
    const vec3 p = v3(0.05f, -0.1f, 0.0f);
    for (int i = 0; i < 5; i++) {
        /* The probe: the direction of the light's sample at (0.4, 0.3), a cone of 0.02 rad. */
        pn_light_sample ls;
        CHECK(pn_light_sample_point(&L, &l[i], p, 0.4f, 0.3f, &ls));
        const vec3 probe = ls.wi;
        /* The cone's test by the sine of the angle, in double (1 - cos of 2e-4 rad is below float's
         * resolution). */
        const double angle = i == 1 ? 2e-4 : 0.02, sin_cone = sin(angle);
        const double cone = 6.283185307179586 * (1.0 - cos(angle));
        const int count = 2000000;
        pn_rng rng;
        pn_rng_seed(&rng, 17, (uint64_t)i);
        int in = 0;
        for (int k = 0; k < count; k++)
            if (pn_light_sample_point(&L, &l[i], p, pn_rng_float(&rng), pn_rng_float(&rng), &ls)) {
                const double ax = ls.wi.x, ay = ls.wi.y, az = ls.wi.z, bx = probe.x, by = probe.y, bz = probe.z;
                const double x = ay * bz - az * by, y = az * bx - ax * bz, z = ax * by - ay * bx;
                in += v3_dot(ls.wi, probe) > 0.0f && sqrt(x * x + y * y + z * z) < sin_cone;
            }
        const double density = (double)in / count / cone;
        const double sd = sqrt((double)in) / count / cone;
        /* The PDF at the probe: the distance along it to the light's surface. */
        pn_light_sample at;
        CHECK(pn_light_sample_point(&L, &l[i], p, 0.4f, 0.3f, &at));
        const double mine = (double)pn_light_pdf_direction(&l[i], p, at.wi, at.dist);
        fprintf(stderr, "  light %d: pn_light_pdf_direction %.5g, histogram %.5g +- %.2g, sampler's own %.5g\n", i,
                mine, density, sd, (double)at.pdf);
        CHECK_MSG(fabs(mine - density) < 4.0 * sd + 0.01 * mine, "light %d: %.5g against %.5g", i, mine, density);
        CHECK_MSG(fabs(mine - (double)at.pdf) <= 1e-3 * (double)at.pdf, "light %d: %.6g, the sample's pdf %.6g", i,
                  mine, (double)at.pdf);
    }
    /* From behind a one-sided light: no density. */
    CHECK(pn_light_pdf_direction(&l[0], v3(0, 0, 2), v3(0, 0, -1), 1.0f) == 0.0f);
    CHECK(pn_ias_mis_weight(1.0, 0.0) == 1.0 && pn_ias_mis_weight(0.0, 1.0) == 0.0);
    CHECK_NEAR(pn_ias_mis_weight(2.0, 1.0) + pn_ias_mis_weight(1.0, 2.0), 1.0, 1e-12);
}

static char tmpdir[256];

/* A 1 x 1 m emitting quad at 1.5 m over a plane, seen from the side so that the quad's mirror
 * image is in view: with `glossy` the plane is coated (pbrt-v4 coateddiffuse, roughness 0.03
 * without remapping: Blinn exponent 2220 under the coating's ~0.04), else diffuse. */
static const char *scene_text(bool glossy) {
    static char text[4096];
    snprintf(
        text, sizeof text,
        "LookAt 0 2 4  0 0 0.8  0 1 0\n"
        "Camera \"perspective\" \"float fov\" [ 40 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n"
        "WorldBegin\n"
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
        "  Shape \"bilinearmesh\" \"point3 P\" [ -0.5 1.5 -0.5  0.5 1.5 -0.5  -0.5 1.5 0.5  0.5 1.5 0.5 ]\n"
        "AttributeEnd\n"
        "%s"
        "Shape \"trianglemesh\" \"point3 P\" [ -4 0 -4  4 0 -4  4 0 4  -4 0 4 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n",
        glossy ? "Material \"coateddiffuse\" \"rgb reflectance\" [ 0.3 0.3 0.3 ] \"float roughness\" [ 0.03 ] "
                 "\"bool remaproughness\" false\n"
               : "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n");
    return text;
}

static pn_image render(pn_context ctx, pn_scene scene, pn_integrator_kind kind, uint32_t spp, const char *mis,
                       bool paper, uint64_t seed) {
    /* Two passes for every pixel, the light guide off in every mode (ias-mis turns it off, ias.c):
     * the modes are compared on the same light samples. */
    const char *const opts[] = {"ias-mis",
                                mis,
                                "max-passes",
                                "2",
                                "ias-aa-threshold",
                                "0",
                                "ias-light-guide",
                                "off",
                                "ias-variant",
                                paper ? "paper" : "default",
                                NULL};
    return pn_test_render_modes(ctx, scene, kind, spp, seed, 1, mis ? opts : NULL);
}

static pn_scene load(pn_context ctx, const char *name, bool glossy) {
    const char *path = pn_test_write_file(tmpdir, name, scene_text(glossy));
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    return scene;
}

static void test_renders(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load(ctx, "mis.pbrt", true);
    pn_image ref = scene ? render(ctx, scene, PN_INTEGRATOR_REFERENCE, 1024, NULL, false, 11) : NULL;
    CHECK(ref != NULL);
    if (ref) {
        const int np = pn_image_width(ref) * pn_image_height(ref);
        const size_t nps = (size_t)(np > 0 ? np : 1);
        const float *r = pn_image_layer_data(ref, 0);
        double ref_sum = 0.0, ref_max = 0.0;
        for (int i = 0; i < np; i++) {
            ref_sum += pn_test_lum_at(r, i);
            ref_max = fmax(ref_max, pn_test_lum_at(r, i));
        }
        /* The highlight: pixels above a quarter of the brightest (the coated plane's base alone
         * is below 0.6 of the pixel values there). */
        unsigned char *hl = calloc(nps, 1);
        int n_hl = 0;
        for (int i = 0; i < np; i++) n_hl += (hl[i] = pn_test_lum_at(r, i) > 0.25 * ref_max);
        CHECK(n_hl > 10 && n_hl < np / 3);
        static const char *const modes[] = {"off", "glossy", "on"};
        enum { SEEDS = 4 };
        double mean[3] = {0}, mean2[3] = {0}, var_hl[3] = {0};
        for (int m = 0; m < 3; m++) {
            double *sum = calloc(nps, sizeof *sum), *sum2 = calloc(nps, sizeof *sum2);
            CHECK(sum && sum2 && hl);
            if (!sum || !sum2 || !hl) break;
            for (int k = 0; k < SEEDS; k++) {
                pn_image img = render(ctx, scene, PN_INTEGRATOR_IAS, 0, modes[m], false, (uint64_t)k);
                CHECK(img != NULL);
                if (!img) continue;
                const float *b = pn_image_layer_data(img, 0);
                double s = 0.0;
                for (int i = 0; i < np; i++) {
                    const double y = pn_test_lum_at(b, i);
                    s += y;
                    sum[i] += y;
                    sum2[i] += y * y;
                }
                mean[m] += s / ref_sum / SEEDS;
                mean2[m] += (s / ref_sum) * (s / ref_sum) / SEEDS;
                pn_image_free(img);
            }
            /* The highlight's per-pixel variance across seeds, relative to the reference. */
            for (int i = 0; i < np; i++) {
                if (!hl[i]) continue;
                const double mu = sum[i] / SEEDS, v = fmax(0.0, sum2[i] / SEEDS - mu * mu) * SEEDS / (SEEDS - 1.0);
                const double y = pn_test_lum_at(r, i);
                var_hl[m] += v / (y * y + 0.01) / n_hl;
            }
            free(sum);
            free(sum2);
        }
        for (int m = 0; m < 3; m++) {
            const double sd = sqrt(fmax(0.0, mean2[m] - mean[m] * mean[m]) * SEEDS / (SEEDS - 1.0) / SEEDS);
            fprintf(stderr, "  ias-mis %-6s mean over the reference's %.5f +- %.5f; highlight relative variance %.3g\n",
                    modes[m], mean[m], sd, var_hl[m]);
            /* Unbiased: within four standard errors of the seeds' mean, plus 0.3% for the
             * reference's own noise (its highlight is light-sampled too). */
            CHECK_MSG(fabs(mean[m] - 1.0) < 4.0 * sd + 0.003, "ias-mis %s: mean %.5f of the reference (+- %.5f)",
                      modes[m], mean[m], sd);
        }
        /* Where light sampling misses the narrow lobe, the paired BSDF rays find it. */
        CHECK_MSG(var_hl[1] < 0.5 * var_hl[0], "glossy: highlight variance %.3g, off %.3g", var_hl[1], var_hl[0]);
        CHECK_MSG(var_hl[2] < 0.5 * var_hl[0], "on: highlight variance %.3g, off %.3g", var_hl[2], var_hl[0]);
        free(hl);
    }
    pn_image_free(ref);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static bool same_image(pn_image a, pn_image b) {
    if (!a || !b) return false;
    const int n = pn_image_width(a) * pn_image_height(a) * 3;
    return n == pn_image_width(b) * pn_image_height(b) * 3 &&
           memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(b, 0), (size_t)n * sizeof(float)) == 0;
}

/* Where MIS does nothing, the images are the light-sampling ones bit for bit. */
static void test_bit_identical(void) {
    pn_context ctx = pn_context_new();
    pn_scene matte = load(ctx, "matte.pbrt", false), glossy = load(ctx, "glossy.pbrt", true);
    pn_image a = matte ? render(ctx, matte, PN_INTEGRATOR_IAS, 0, "off", false, 3) : NULL;
    pn_image b = matte ? render(ctx, matte, PN_INTEGRATOR_IAS, 0, "glossy", false, 3) : NULL;
    pn_image c = matte ? render(ctx, matte, PN_INTEGRATOR_IAS, 0, "on", false, 3) : NULL;
    CHECK(same_image(a, b));  /* no glossy lobe: 'glossy' is 'off' */
    CHECK(!same_image(a, c)); /* 'on' does add BSDF rays there */
    pn_image d = glossy ? render(ctx, glossy, PN_INTEGRATOR_IAS, 0, "off", true, 3) : NULL;
    pn_image e = glossy ? render(ctx, glossy, PN_INTEGRATOR_IAS, 0, "on", true, 3) : NULL;
    CHECK(same_image(d, e)); /* the paper variant ignores it */
    pn_image_free(a);
    pn_image_free(b);
    pn_image_free(c);
    pn_image_free(d);
    pn_image_free(e);
    pn_scene_free(matte);
    pn_scene_free(glossy);
    pn_context_free(ctx);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_ias_mis_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void test_teardown(void) {
    static const char *const names[] = {"mis.pbrt", "matte.pbrt", "glossy.pbrt"};
    char path[600];
    for (int i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s/%s", tmpdir, names[i]);
        unlink(path);
    }
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(test_bsdf_sampling), TEST(test_light_pdf), TEST(test_setup), TEST(test_renders), TEST(test_bit_identical),
         TEST(test_teardown))
