/* test_lights.c — light sampling and irradiance against closed forms: rectangle, disk, sphere,
 * triangle, point and spot lights; equal-area mapping round trip; polygon clipping. */
#include "harness.h"

#include "core/sobol.h"
#include "lights/lights.h"

/* Form factor from a differential area to a parallel a x b rectangle with one corner above the
 * receiver at height h (the standard closed form, e.g. Howell's catalogue, configuration B-3). */
static double corner_rectangle_form_factor(double a, double b, double h) {
    double A = a / h, B = b / h;
    double sa = sqrt(1.0 + A * A), sb = sqrt(1.0 + B * B);
    return (A / sa * atan(B / sa) + B / sb * atan(A / sb)) / (2.0 * M_PI);
}

/* Monte Carlo irradiance at p (normal n) from light l with N scrambled Sobol samples. */
static double sampled_irradiance(const pn_lights *L, const pn_light *l, vec3 p, vec3 n, uint32_t N) {
    double sum = 0.0;
    for (uint32_t i = 0; i < N; i++) {
        pn_light_sample s;
        if (!pn_light_sample_point(L, l, p, pn_sobol_sample(i, 0, 7u), pn_sobol_sample(i, 1, 7u), &s)) continue;
        float c = v3_dot(n, s.wi);
        if (c <= 0.0f) continue;
        sum += (double)(s.radiance.y * c / s.pdf);
    }
    return sum / (double)N;
}

static pn_lights make_lights(pn_light *l) {
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = l;
    L.count = 1;
    L.scene_radius = 10.0f;
    return L;
}

static pn_light square_light(float side, float height) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = PN_LIGHT_RECTANGLE;
    l.p = v3(-0.5f * side, -0.5f * side, height);
    l.e1 = v3(0, side, 0);
    l.e2 = v3(side, 0, 0);
    l.n = v3(0, 0, -1); /* cross(e1, e2) = (0,0,-side^2): facing down */
    l.area = side * side;
    l.emit = v3(2, 2, 2);
    l.env = -1;
    return l;
}

static void test_rectangle_closed_form(void) {
    pn_light l = square_light(1.0f, 0.7f);
    pn_lights L = make_lights(&l);
    double expected = 2.0 * M_PI * 4.0 * corner_rectangle_form_factor(0.5, 0.5, 0.7);
    vec3 p = v3(0, 0, 0), n = v3(0, 0, 1);
    double exact = (double)pn_light_irradiance_estimate(&L, &l, p, n); /* luminance of (2,2,2) = 2 */
    CHECK_NEAR(exact, expected, 1e-4 * expected);
    double mc = sampled_irradiance(&L, &l, p, n, 4096);
    CHECK_NEAR(mc, expected, 0.005 * expected);
    /* Close to the light, where area sampling would be noisy, solid-angle sampling stays exact. */
    l = square_light(1.0f, 0.05f);
    expected = 2.0 * M_PI * 4.0 * corner_rectangle_form_factor(0.5, 0.5, 0.05);
    mc = sampled_irradiance(&L, &l, p, n, 4096);
    CHECK_NEAR(mc, expected, 0.005 * expected);
    /* Behind a one-sided light: nothing. */
    CHECK(pn_light_irradiance_estimate(&L, &l, v3(0, 0, 1), v3(0, 0, -1)) == 0.0f);
}

static void test_disk_closed_form(void) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = PN_LIGHT_DISK;
    l.p = v3(0, 0, 1.5f);
    l.n = v3(0, 0, -1);
    l.radius = 0.8f;
    l.area = (float)M_PI * 0.64f;
    l.emit = v3(1, 1, 1);
    l.env = -1;
    pn_lights L = make_lights(&l);
    double expected = M_PI * 0.64 / (1.5 * 1.5 + 0.64);
    double mc = sampled_irradiance(&L, &l, v3(0, 0, 0), v3(0, 0, 1), 8192);
    CHECK_NEAR(mc, expected, 0.005 * expected);
    /* The 24-gon estimate is within 1.2 % (its area is 98.9 % of the disk's). */
    double est = pn_light_irradiance_estimate(&L, &l, v3(0, 0, 0), v3(0, 0, 1));
    CHECK_NEAR(est, expected, 0.012 * expected);
}

static void test_sphere_closed_form(void) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = PN_LIGHT_SPHERE;
    l.p = v3(0.6f, 0, 2.0f);
    l.radius = 0.5f;
    l.area = 4.0f * (float)M_PI * 0.25f;
    l.emit = v3(3, 3, 3);
    l.env = -1;
    pn_lights L = make_lights(&l);
    double d = sqrt(0.36 + 4.0);
    double cos_t = 2.0 / d;
    double expected = M_PI * 3.0 * (0.25 / (d * d)) * cos_t;
    double mc = sampled_irradiance(&L, &l, v3(0, 0, 0), v3(0, 0, 1), 8192);
    CHECK_NEAR(mc, expected, 0.005 * expected);
    double est = pn_light_irradiance_estimate(&L, &l, v3(0, 0, 0), v3(0, 0, 1));
    CHECK_NEAR(est, expected, 1e-3 * expected);
}

static void test_triangle_matches_half_rectangle(void) {
    /* Two triangles splitting a square give, together, the square's irradiance. */
    pn_light sq = square_light(1.0f, 0.6f);
    pn_light t1 = sq, t2 = sq;
    t1.kind = t2.kind = PN_LIGHT_TRIANGLE;
    t1.e1 = sq.e1;
    t1.e2 = v3_add(sq.e1, sq.e2);
    t2.e1 = v3_add(sq.e1, sq.e2);
    t2.e2 = sq.e2;
    t1.area = t2.area = 0.5f;
    pn_lights L = make_lights(&sq);
    vec3 p = v3(0.1f, -0.2f, 0), n = v3(0, 0, 1);
    double e_sq = pn_light_irradiance_estimate(&L, &sq, p, n);
    double e_tri = pn_light_irradiance_estimate(&L, &t1, p, n) + pn_light_irradiance_estimate(&L, &t2, p, n);
    CHECK_NEAR(e_tri, e_sq, 1e-4 * e_sq);
    double mc = sampled_irradiance(&L, &t1, p, n, 8192) + sampled_irradiance(&L, &t2, p, n, 8192);
    CHECK_NEAR(mc, e_sq, 0.005 * e_sq);
}

static void test_polygon_clipped_by_horizon(void) {
    /* A vertical square straddling the receiver's tangent plane: the exact (clipped) value must
     * match Monte Carlo integration of the cosine over the visible part. */
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = PN_LIGHT_RECTANGLE;
    l.p = v3(-0.5f, 1.0f, -0.5f);
    l.e1 = v3(1, 0, 0);
    l.e2 = v3(0, 0, 1);
    l.n = v3(0, -1, 0);
    l.area = 1.0f;
    l.emit = v3(1, 1, 1);
    l.two_sided = true;
    l.env = -1;
    pn_lights L = make_lights(&l);
    vec3 p = v3(0, 0, 0), n = v3(0, 0, 1);
    double est = pn_light_irradiance_estimate(&L, &l, p, n);
    double mc = sampled_irradiance(&L, &l, p, n, 16384);
    CHECK(est > 0.0);
    CHECK_NEAR(est, mc, 0.01 * est);
}

static void test_point_and_spot(void) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = PN_LIGHT_SPOT;
    l.p = v3(0, 0, 2);
    l.n = v3(0, 0, -1);
    l.emit = v3(4, 4, 4);
    l.cos_total_width = cosf(30.0f * (float)M_PI / 180.0f);
    l.cos_falloff_start = cosf(25.0f * (float)M_PI / 180.0f);
    l.env = -1;
    pn_lights L = make_lights(&l);
    pn_light_sample s;
    CHECK(pn_light_sample_point(&L, &l, v3(0, 0, 0), 0.5f, 0.5f, &s));
    CHECK(s.delta);
    CHECK_NEAR(s.radiance.x, 1.0, 1e-6); /* 4 / 2^2 */
    /* Outside the cone: nothing. */
    CHECK(!pn_light_sample_point(&L, &l, v3(3, 0, 0), 0.5f, 0.5f, &s));
    /* In the falloff ring: smoothstep between 0 and 1. */
    float x = 2.0f * tanf(27.5f * (float)M_PI / 180.0f);
    CHECK(pn_light_sample_point(&L, &l, v3(x, 0, 0), 0.5f, 0.5f, &s));
    float d2 = x * x + 4.0f;
    CHECK(s.radiance.x > 0.0f && s.radiance.x < 4.0f / d2);
}

static void test_equal_area_round_trip(void) {
    int bad = 0;
    for (int i = 0; i < 64; i++)
        for (int j = 0; j < 64; j++) {
            float u = ((float)i + 0.37f) / 64.0f, v = ((float)j + 0.61f) / 64.0f;
            vec3 d = pn_equal_area_square_to_sphere(u, v);
            if (fabsf(v3_length(d) - 1.0f) > 1e-4f) bad++;
            float u2, v2;
            pn_equal_area_sphere_to_square(d, &u2, &v2);
            if (fabsf(u2 - u) > 1e-4f || fabsf(v2 - v) > 1e-4f) bad++;
        }
    CHECK_MSG(bad == 0, "%d mismatches", bad);
}

PN_TESTS(TEST(test_rectangle_closed_form), TEST(test_disk_closed_form), TEST(test_sphere_closed_form),
         TEST(test_triangle_matches_half_rectangle), TEST(test_polygon_clipped_by_horizon), TEST(test_point_and_spot),
         TEST(test_equal_area_round_trip))
