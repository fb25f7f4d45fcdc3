/* test_env_regions.c — the equal-energy environment partition (IAS paper §4.3, §5.1): exact
 * tiling, region count, energy balance, pre-integration against quadrature, sampling inside a
 * region (containment, pdf, chi-square, unbiased estimates of the region integral) and the
 * conservative horizon cull. Maps are synthetic pn_env records built in memory. */
#include "harness.h"

#include "core/rng.h"
#include "lights/env_regions.h"

#include <stdint.h>

#define TPI 3.14159265358979323846

typedef struct test_map {
    pn_env env;
    float *rgb;
} test_map;

/* Light-space direction of grid position (u, v) in [0,1]^2, written independently of the
 * library for lat-long maps. */
static vec3 map_direction(bool equal_area, double u, double v) {
    if (equal_area) return pn_equal_area_square_to_sphere((float)u, (float)v);
    double theta = v * TPI, phi = u * 2.0 * TPI;
    return v3((float)(sin(theta) * cos(phi)), (float)(sin(theta) * sin(phi)), (float)cos(theta));
}

static double texel_solid_angle(bool equal_area, int w, int h, int y) {
    if (equal_area) return 4.0 * TPI / ((double)w * (double)h);
    return (2.0 * TPI / w) * (cos(TPI * y / h) - cos(TPI * (y + 1) / h));
}

/* kind 0: smooth and colourful; kind 1: the same plus a small bright "sun". */
static vec3 map_radiance(vec3 d, int kind) {
    float r = 1.0f + 0.6f * sinf(3.0f * d.x) * cosf(2.0f * d.y);
    float g = 1.2f + 0.5f * d.z;
    float b = 0.8f + 0.7f * d.y * d.y;
    vec3 c = v3(r, g, b);
    if (kind == 1) {
        vec3 s = v3_normalize(v3(0.3f, -0.5f, 0.8f));
        float k = expf(-(1.0f - v3_dot(d, s)) * 400.0f) * 200.0f;
        c = v3_add(c, v3(k, 0.9f * k, 0.6f * k));
    }
    return c;
}

static void map_transforms(pn_env *env, bool rotated) {
    env->world_from_light = rotated ? mat4_rotate(37.0, 1.0, 2.0, -0.5) : mat4_identity();
    CHECK(mat4_inverse(env->world_from_light, &env->light_from_world));
}

static test_map make_map(int w, int h, bool equal_area, int kind, bool rotated) {
    test_map m;
    memset(&m, 0, sizeof m);
    m.rgb = malloc((size_t)w * (size_t)h * 3 * sizeof(float));
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            vec3 d = map_direction(equal_area, (x + 0.5) / w, (y + 0.5) / h);
            vec3 c = map_radiance(d, kind);
            float *px = m.rgb + 3 * ((size_t)y * (size_t)w + (size_t)x);
            px[0] = c.x;
            px[1] = c.y;
            px[2] = c.z;
        }
    m.env.width = w;
    m.env.height = h;
    m.env.rgb = m.rgb;
    m.env.scale = v3(1.0f, 1.0f, 1.0f);
    m.env.equal_area = equal_area;
    map_transforms(&m.env, rotated);
    return m;
}

static test_map make_constant(vec3 c) {
    test_map m;
    memset(&m, 0, sizeof m);
    m.env.constant = c;
    m.env.scale = v3(1.0f, 1.0f, 1.0f);
    map_transforms(&m.env, true);
    return m;
}

static vec3 texel_value(const test_map *m, int x, int y) {
    if (!m->rgb) return m->env.constant;
    const float *px = m->rgb + 3 * ((size_t)y * (size_t)m->env.width + (size_t)x);
    return v3_mul(v3(px[0], px[1], px[2]), m->env.scale);
}

static bool build(const test_map *m, int target, pn_env_regions *r) {
    pn_err err;
    pn_err_init(&err);
    pn_status st = pn_env_regions_build(&m->env, target, r, &err);
    CHECK_MSG(st == PN_OK, "%s", err.message);
    return st == PN_OK;
}

/* Each texel in exactly one region rectangle, and the region index agrees with
 * pn_env_region_of at the texel centre. */
static void check_tiling(const test_map *m, const pn_env_regions *r) {
    int w = r->width, h = r->height;
    int *cover = calloc((size_t)w * (size_t)h, sizeof *cover);
    int *owner = malloc((size_t)w * (size_t)h * sizeof *owner);
    int bad_rect = 0;
    for (int k = 0; k < r->count; k++) {
        const pn_env_region *g = &r->regions[k];
        if (!(g->x0 >= 0 && g->x0 < g->x1 && g->x1 <= w && g->y0 >= 0 && g->y0 < g->y1 && g->y1 <= h)) {
            bad_rect++;
            continue;
        }
        for (int y = g->y0; y < g->y1; y++)
            for (int x = g->x0; x < g->x1; x++) {
                cover[y * w + x]++;
                owner[y * w + x] = k;
            }
    }
    CHECK(bad_rect == 0);
    int wrong_cover = 0, wrong_owner = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            if (cover[y * w + x] != 1) {
                wrong_cover++;
                continue;
            }
            vec3 dl = map_direction(r->equal_area, (x + 0.5) / w, (y + 0.5) / h);
            vec3 dw = mat4_apply_vector(&m->env.world_from_light, dl);
            if (pn_env_region_of(r, &m->env, dw) != owner[y * w + x]) wrong_owner++;
        }
    CHECK_MSG(wrong_cover == 0, "%d texels not covered exactly once", wrong_cover);
    CHECK_MSG(wrong_owner == 0, "%d texel centres map to another region", wrong_owner);
    free(cover);
    free(owner);
}

static void test_tiling_and_count(void) {
    const struct {
        int w, h;
        bool ea;
    } maps[] = {{64, 64, true}, {128, 64, false}, {64, 32, false}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        test_map m = make_map(maps[i].w, maps[i].h, maps[i].ea, 1, true);
        pn_env_regions r;
        if (build(&m, 300, &r)) {
            CHECK_MSG(r.count == 300, "%dx%d: %d regions", maps[i].w, maps[i].h, r.count);
            check_tiling(&m, &r);
            pn_env_regions_free(&r);
        }
        free(m.rgb);
    }
}

static void test_energy_balance(void) {
    const struct {
        int w, h;
        bool ea;
    } maps[] = {{64, 64, true}, {128, 64, false}, {256, 128, false}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        test_map m = make_map(maps[i].w, maps[i].h, maps[i].ea, 0, false);
        pn_env_regions r;
        if (build(&m, 300, &r)) {
            double lo = INFINITY, hi = 0.0;
            for (int k = 0; k < r.count; k++) {
                lo = fmin(lo, (double)r.regions[k].power);
                hi = fmax(hi, (double)r.regions[k].power);
            }
            fprintf(stderr, "  %dx%d %s: %d regions, power max/min = %.3f\n", maps[i].w, maps[i].h,
                    maps[i].ea ? "equal-area" : "lat-long", r.count, hi / lo);
            CHECK(lo > 0.0);
            CHECK_MSG(hi / lo < 3.0, "max/min %.3f", hi / lo);
            pn_env_regions_free(&r);
        }
        free(m.rgb);
    }
}

static void test_integrals(void) {
    const struct {
        int w, h;
        bool ea;
    } maps[] = {{64, 64, true}, {128, 64, false}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        test_map m = make_map(maps[i].w, maps[i].h, maps[i].ea, 1, true);
        m.env.scale = v3(0.5f, 2.0f, 1.5f);
        int w = maps[i].w, h = maps[i].h;
        double q[3] = {0.0, 0.0, 0.0}, omega = 0.0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                double om = texel_solid_angle(maps[i].ea, w, h, y);
                vec3 c = texel_value(&m, x, y);
                q[0] += om * (double)c.x;
                q[1] += om * (double)c.y;
                q[2] += om * (double)c.z;
                omega += om;
            }
        CHECK_NEAR(omega, 4.0 * TPI, 1e-9);
        pn_env_regions r;
        if (build(&m, 300, &r)) {
            double s[3] = {0.0, 0.0, 0.0}, so = 0.0, sp = 0.0;
            for (int k = 0; k < r.count; k++) {
                s[0] += (double)r.regions[k].irradiance_rgb_integral.x;
                s[1] += (double)r.regions[k].irradiance_rgb_integral.y;
                s[2] += (double)r.regions[k].irradiance_rgb_integral.z;
                so += (double)r.regions[k].solid_angle;
                sp += (double)r.regions[k].power;
            }
            for (int c = 0; c < 3; c++) CHECK_NEAR(s[c] / q[c], 1.0, 1e-4);
            CHECK_NEAR(so / (4.0 * TPI), 1.0, 1e-4);
            double ql = 0.2126 * q[0] + 0.7152 * q[1] + 0.0722 * q[2];
            CHECK_NEAR(sp / ql, 1.0, 1e-4);
            CHECK_NEAR(r.total_power / ql, 1.0, 1e-4);
            pn_env_regions_free(&r);
        }
        free(m.rgb);
    }
}

/* Samples every region: containment, pdf and radiance against the texel, chi-square of the
 * texel histogram pooled over regions, and E[L / pdf] against the pre-integrated value. */
static void check_sampling(const test_map *m, const pn_env_regions *r, int per_region, uint64_t seed) {
    int w = r->width, h = r->height;
    bool ea = r->equal_area;
    pn_rng rng;
    pn_rng_seed(&rng, seed, 7);
    double *expect = malloc((size_t)w * (size_t)h * sizeof *expect);
    int *hits = malloc((size_t)w * (size_t)h * sizeof *hits);
    double chi2 = 0.0;
    int dof = 0, outside = 0, bad_pdf = 0, bad_rad = 0, bad_pdf_fn = 0, failed = 0, worst_k = -1;
    double worst_rel = 0.0;
    for (int k = 0; k < r->count; k++) {
        const pn_env_region *g = &r->regions[k];
        double wk = 0.0;
        for (int y = g->y0; y < g->y1; y++)
            for (int x = g->x0; x < g->x1; x++) {
                double lum = fmax(0.0, (double)v3_luminance(texel_value(m, x, y)));
                expect[y * w + x] = lum * texel_solid_angle(ea, w, h, y);
                hits[y * w + x] = 0;
                wk += expect[y * w + x];
            }
        if (!(g->power > 0.0f)) {
            vec3 wi, rad;
            float pdf;
            CHECK(!pn_env_region_sample(r, &m->env, k, 0.5f, 0.5f, &wi, &rad, &pdf));
            continue;
        }
        double est[3] = {0.0, 0.0, 0.0};
        for (int s = 0; s < per_region; s++) {
            /* Independent numbers, so that the texel counts are multinomial. */
            float u1 = pn_rng_float(&rng), u2 = pn_rng_float(&rng);
            vec3 wi, rad;
            float pdf;
            if (!pn_env_region_sample(r, &m->env, k, u1, u2, &wi, &rad, &pdf)) {
                failed++;
                continue;
            }
            if (pn_env_region_of(r, &m->env, wi) != k) outside++;
            vec3 wl = v3_normalize(mat4_apply_vector(&m->env.light_from_world, wi));
            float lu, lv;
            if (m->rgb) {
                (void)pn_env_lookup(&m->env, wl, &lu, &lv);
            } else {
                pn_equal_area_sphere_to_square(wl, &lu, &lv);
            }
            int x = (int)(lu * (float)w), y = (int)(lv * (float)h);
            x = x < 0 ? 0 : (x >= w ? w - 1 : x);
            y = y < 0 ? 0 : (y >= h ? h - 1 : y);
            if (x >= g->x0 && x < g->x1 && y >= g->y0 && y < g->y1) hits[y * w + x]++;
            double want = expect[y * w + x] / texel_solid_angle(ea, w, h, y) / wk;
            if (!(fabs((double)pdf / want - 1.0) < 1e-4)) bad_pdf++;
            vec3 tv = texel_value(m, x, y);
            if (fabsf(tv.x - rad.x) > 1e-6f * fabsf(tv.x) || fabsf(tv.y - rad.y) > 1e-6f * fabsf(tv.y)) bad_rad++;
            if (!(fabsf(pn_env_region_pdf(r, &m->env, k, wi) - pdf) <= 1e-6f * pdf)) bad_pdf_fn++;
            est[0] += (double)rad.x / (double)pdf;
            est[1] += (double)rad.y / (double)pdf;
            est[2] += (double)rad.z / (double)pdf;
        }
        vec3 ref = g->irradiance_rgb_integral;
        double rv[3] = {ref.x, ref.y, ref.z};
        for (int c = 0; c < 3; c++) {
            double rel = fabs(est[c] / per_region / rv[c] - 1.0);
            if (rel > worst_rel) {
                worst_rel = rel;
                worst_k = k;
            }
        }
        /* Chi-square over the region's texels; cells expecting < 5 hits are pooled. */
        double pool_e = 0.0, pool_o = 0.0;
        int cells = 0;
        for (int y = g->y0; y < g->y1; y++)
            for (int x = g->x0; x < g->x1; x++) {
                double e = expect[y * w + x] / wk * per_region;
                double o = hits[y * w + x];
                if (e < 5.0) {
                    pool_e += e;
                    pool_o += o;
                    continue;
                }
                chi2 += (o - e) * (o - e) / e;
                cells++;
            }
        if (pool_e >= 5.0) {
            chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            cells++;
        }
        if (cells > 1) dof += cells - 1;
    }
    double z = dof > 0 ? (chi2 - dof) / sqrt(2.0 * dof) : 0.0;
    fprintf(stderr, "  %dx%d %s: chi2 %.1f dof %d (z %.2f), worst region estimate error %.4f%% (region %d)\n", w, h,
            r->virtual_grid ? "constant" : (ea ? "equal-area" : "lat-long"), chi2, dof, z, 100.0 * worst_rel, worst_k);
    CHECK_MSG(outside == 0, "%d samples outside their region", outside);
    CHECK_MSG(failed == 0, "%d samples failed", failed);
    CHECK_MSG(bad_pdf == 0, "%d pdfs differ from luminance / region energy", bad_pdf);
    CHECK_MSG(bad_rad == 0, "%d radiances differ from the texel", bad_rad);
    CHECK_MSG(bad_pdf_fn == 0, "%d pn_env_region_pdf mismatches", bad_pdf_fn);
    CHECK_MSG(fabs(z) < 4.0, "chi-square z %.2f", z);
    CHECK_MSG(worst_rel < 0.01, "region integral estimate off by %.4f", worst_rel);
    free(expect);
    free(hits);
}

static void test_sampling(void) {
    const struct {
        int w, h;
        bool ea;
    } maps[] = {{64, 64, true}, {128, 64, false}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        test_map m = make_map(maps[i].w, maps[i].h, maps[i].ea, 1, true);
        pn_env_regions r;
        if (build(&m, 300, &r)) {
            check_sampling(&m, &r, 4000, 1234 + i);
            pn_env_regions_free(&r);
        }
        free(m.rgb);
    }
}

/* Every texel corner and centre of a culled region must be on or below the plane; and a useful
 * share of the regions gets culled. */
static void check_cull(const test_map *m, const pn_env_regions *r, uint64_t seed) {
    int w = r->width, h = r->height;
    vec3 *corner = malloc((size_t)(w + 1) * (size_t)(h + 1) * sizeof *corner);
    vec3 *centre = malloc((size_t)w * (size_t)h * sizeof *centre);
    for (int y = 0; y <= h; y++)
        for (int x = 0; x <= w; x++)
            corner[y * (w + 1) + x] = v3_normalize(mat4_apply_vector(
                &m->env.world_from_light, map_direction(r->equal_area, (double)x / w, (double)y / h)));
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            centre[y * w + x] = v3_normalize(mat4_apply_vector(
                &m->env.world_from_light, map_direction(r->equal_area, (x + 0.5) / w, (y + 0.5) / h)));
    pn_rng rng;
    pn_rng_seed(&rng, seed, 3);
    long culled = 0, total = 0, wrong = 0, sample_wrong = 0;
    double half_angle = 0.0;
    for (int k = 0; k < r->count; k++) half_angle += acos(fmax(-1.0, (double)r->regions[k].cos_extent));
    for (int trial = 0; trial < 200; trial++) {
        vec3 n = pn_sample_uniform_sphere(pn_rng_float(&rng), pn_rng_float(&rng));
        if (trial < 6) n = v3(trial == 0 ? 1.0f : 0.0f, trial == 1 ? 1.0f : 0.0f, trial == 2 ? 1.0f : 0.0f);
        if (trial >= 3 && trial < 6)
            n = v3_neg(v3(trial == 3 ? 1.0f : 0.0f, trial == 4 ? 1.0f : 0.0f, trial == 5 ? 1.0f : 0.0f));
        n = v3_scale(n, 2.5f); /* need not be unit */
        for (int k = 0; k < r->count; k++) {
            const pn_env_region *g = &r->regions[k];
            bool below = pn_env_region_below(g, n);
            total++;
            if (!below) continue;
            culled++;
            float top = -INFINITY;
            for (int y = g->y0; y < g->y1; y++)
                for (int x = g->x0; x < g->x1; x++) {
                    top = fmaxf(top, v3_dot(centre[y * w + x], n));
                    top = fmaxf(top, v3_dot(corner[y * (w + 1) + x], n));
                    top = fmaxf(top, v3_dot(corner[y * (w + 1) + x + 1], n));
                    top = fmaxf(top, v3_dot(corner[(y + 1) * (w + 1) + x], n));
                    top = fmaxf(top, v3_dot(corner[(y + 1) * (w + 1) + x + 1], n));
                }
            if (top > 1e-6f) wrong++;
            for (int s = 0; s < 4; s++) {
                vec3 wi, rad;
                float pdf;
                if (pn_env_region_sample(r, &m->env, k, pn_rng_float(&rng), pn_rng_float(&rng), &wi, &rad, &pdf) &&
                    v3_dot(wi, n) > 0.0f)
                    sample_wrong++;
            }
        }
    }
    fprintf(stderr, "  %s: culled %.1f%% of region/normal pairs, mean cone half-angle %.2f deg\n",
            r->virtual_grid ? "constant" : (r->equal_area ? "equal-area" : "lat-long"),
            100.0 * (double)culled / (double)total, half_angle / r->count * 180.0 / TPI);
    CHECK_MSG(wrong == 0, "%ld culled regions reach above the plane", wrong);
    CHECK_MSG(sample_wrong == 0, "%ld samples of culled regions above the plane", sample_wrong);
    CHECK_MSG((double)culled > 0.35 * (double)total, "only %ld of %ld culled", culled, total);
    free(corner);
    free(centre);
}

static void test_cull(void) {
    const struct {
        int w, h;
        bool ea;
    } maps[] = {{64, 64, true}, {128, 64, false}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        test_map m = make_map(maps[i].w, maps[i].h, maps[i].ea, 1, true);
        pn_env_regions r;
        if (build(&m, 300, &r)) {
            check_cull(&m, &r, 99 + i);
            pn_env_regions_free(&r);
        }
        free(m.rgb);
    }
    test_map c = make_constant(v3(0.5f, 0.7f, 1.0f));
    pn_env_regions r;
    if (build(&c, 300, &r)) {
        check_cull(&c, &r, 5);
        pn_env_regions_free(&r);
    }
}

static void test_constant(void) {
    test_map m = make_constant(v3(0.5f, 0.7f, 1.0f));
    pn_env_regions r;
    if (!build(&m, 300, &r)) return;
    CHECK(r.virtual_grid);
    CHECK(r.count == 300);
    check_tiling(&m, &r);
    double s[3] = {0.0, 0.0, 0.0}, lo = INFINITY, hi = 0.0;
    for (int k = 0; k < r.count; k++) {
        s[0] += (double)r.regions[k].irradiance_rgb_integral.x;
        s[1] += (double)r.regions[k].irradiance_rgb_integral.y;
        s[2] += (double)r.regions[k].irradiance_rgb_integral.z;
        lo = fmin(lo, (double)r.regions[k].power);
        hi = fmax(hi, (double)r.regions[k].power);
    }
    CHECK_NEAR(s[0] / (4.0 * TPI * 0.5), 1.0, 1e-4);
    CHECK_NEAR(s[1] / (4.0 * TPI * 0.7), 1.0, 1e-4);
    CHECK_NEAR(s[2] / (4.0 * TPI * 1.0), 1.0, 1e-4);
    CHECK(hi / lo <= 2.0 + 1e-4);
    int bad = 0;
    pn_rng rng;
    pn_rng_seed(&rng, 77, 1);
    for (int k = 0; k < r.count; k++)
        for (int i = 0; i < 20; i++) {
            vec3 wi, rad;
            float pdf;
            if (!pn_env_region_sample(&r, &m.env, k, pn_rng_float(&rng), pn_rng_float(&rng), &wi, &rad, &pdf) ||
                rad.x != 0.5f || rad.y != 0.7f || rad.z != 1.0f ||
                fabsf(pdf * r.regions[k].solid_angle - 1.0f) > 1e-4f || pn_env_region_of(&r, &m.env, wi) != k)
                bad++;
        }
    CHECK_MSG(bad == 0, "%d bad samples of the constant map", bad);
    check_sampling(&m, &r, 200, 31);
    pn_env_regions_free(&r);

    /* A black constant map still gets regions, none of them sampled. */
    test_map black = make_constant(v3(0.0f, 0.0f, 0.0f));
    if (build(&black, 50, &r)) {
        CHECK(r.count == 50);
        vec3 wi, rad;
        float pdf;
        for (int k = 0; k < r.count; k++) CHECK(!pn_env_region_sample(&r, &black.env, k, 0.3f, 0.6f, &wi, &rad, &pdf));
        pn_env_regions_free(&r);
    }
}

/* A map with a handful of lit texels: zero-energy regions exist, are never sampled, and the
 * lit texels are still integrated exactly. */
static void test_sparse(void) {
    int w = 64, h = 32;
    test_map m = make_map(w, h, false, 0, false);
    memset(m.rgb, 0, (size_t)w * (size_t)h * 3 * sizeof(float));
    const int lit[5][2] = {{3, 2}, {40, 10}, {41, 10}, {63, 31}, {20, 16}};
    for (int i = 0; i < 5; i++) {
        float *px = m.rgb + 3 * (lit[i][1] * w + lit[i][0]);
        px[0] = 2.0f + (float)i;
        px[1] = 1.0f;
        px[2] = 0.5f;
    }
    pn_env_regions r;
    if (build(&m, 300, &r)) {
        CHECK(r.count <= 300);
        check_tiling(&m, &r);
        int lit_regions = 0;
        for (int k = 0; k < r.count; k++) lit_regions += r.regions[k].power > 0.0f;
        CHECK_MSG(lit_regions == 5, "%d lit regions", lit_regions);
        check_sampling(&m, &r, 100, 3);
        pn_env_regions_free(&r);
    }
    free(m.rgb);
}

/* Degenerate targets: one region, and more regions requested than there are texels. */
static void test_limits(void) {
    test_map m = make_map(8, 8, true, 0, false);
    pn_env_regions r;
    if (build(&m, 1, &r)) {
        CHECK(r.count == 1);
        CHECK(r.regions[0].x0 == 0 && r.regions[0].y0 == 0 && r.regions[0].x1 == 8 && r.regions[0].y1 == 8);
        CHECK(r.regions[0].cos_extent == -1.0f);
        CHECK(!pn_env_region_below(&r.regions[0], v3(0.0f, 0.0f, 1.0f)));
        pn_env_regions_free(&r);
    }
    if (build(&m, 100, &r)) {
        CHECK(r.count == 64);
        check_tiling(&m, &r);
        pn_env_regions_free(&r);
    }
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_env_regions_build(&m.env, 0, &r, &err) == PN_ERROR_INVALID_ARGUMENT);
    pn_env_regions_free(&r);
    free(m.rgb);
}

PN_TESTS(TEST(test_tiling_and_count), TEST(test_energy_balance), TEST(test_integrals), TEST(test_sampling),
         TEST(test_cull), TEST(test_constant), TEST(test_sparse), TEST(test_limits))
