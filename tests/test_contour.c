/* test_contour.c — Approximate Contour Integration (Vedel 1993), the closed forms: eq. 4 on an
 * unoccluded rectangle against the catalogue's corner form factor, horizon clipping, triangles
 * against rectangles split in two, and the gradient of eq. 8-10 against finite differences of
 * the form factor, unoccluded and with a straight occluding edge whose 3D points are used for the
 * silhouette (Fig. 5). */
#include "harness.h"

#include "integrators/contour_math.h"

static pn_dvec3 N_UP = {0, 0, 1};

static double rect_ff_at(pn_dvec3 m, pn_dvec3 n, double x0, double x1, double y0, double y1, double h) {
    pn_contour_source s;
    /* Emitting downwards (towards z < h). */
    pn_contour_source_rectangle(&s, v3((float)x0, (float)y0, (float)h), v3((float)(x1 - x0), 0, 0),
                                v3(0, (float)(y1 - y0), 0), v3(0, 0, -1), false);
    pn_contour_g g;
    pn_contour_source_unoccluded(&s, m, n, n, false, &g);
    return pn_dv3_dot(g.g, n);
}

static void test_rectangle_matches_closed_form(void) {
    const double cases[][3] = {{1, 1, 1}, {2, 0.5, 0.3}, {0.1, 3, 2}, {5, 5, 0.01}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double a = cases[c][0], b = cases[c][1], h = cases[c][2];
        double exact = pn_contour_corner_rectangle_form_factor(a, b, h);
        double f = rect_ff_at(pn_dv3(0, 0, 0), N_UP, 0, a, 0, b, h);
        CHECK_NEAR(f, exact, 1e-7 * exact);
        /* A point under the middle: four corner rectangles. */
        double f4 = rect_ff_at(pn_dv3(a / 2, b / 2, 0), N_UP, 0, a, 0, b, h);
        CHECK_NEAR(f4, 4.0 * pn_contour_corner_rectangle_form_factor(a / 2, b / 2, h), 1e-7 * f4);
    }
    /* Behind a one-sided source: nothing. */
    CHECK(rect_ff_at(pn_dv3(0, 0, 2), N_UP, 0, 1, 0, 1, 1) == 0.0);
    /* A very large source approaches F = 1. */
    CHECK_NEAR(rect_ff_at(pn_dv3(0, 0, 0), N_UP, -1e4, 1e4, -1e4, 1e4, 1), 1.0, 1e-4);
}

static void test_horizon_clipping(void) {
    /* Receiver facing +x under a rectangle at height 1 spanning x in [-1, 1]: only x >= 0 counts.
     * By symmetry, the clipped part is the half source x in [0, 1], seen with normal +x. */
    pn_dvec3 nx = pn_dv3(1, 0, 0);
    double clipped = rect_ff_at(pn_dv3(0, 0, 0), nx, -1, 1, -1, 1, 1);
    double half = rect_ff_at(pn_dv3(0, 0, 0), nx, 0, 1, -1, 1, 1);
    CHECK(half > 0.01);
    CHECK_NEAR(clipped, half, 1e-12);
    /* Tilted receiver: Monte Carlo of cos+ over the rectangle. */
    pn_dvec3 nt = pn_dv3(0.6, 0, 0.8);
    double f = rect_ff_at(pn_dv3(0, 0, 0), nt, -1, 1, -1, 1, 0.5);
    double sum = 0.0;
    int K = 600;
    for (int i = 0; i < K; i++)
        for (int j = 0; j < K; j++) {
            double x = -1 + 2 * (i + 0.5) / K, y = -1 + 2 * (j + 0.5) / K, z = 0.5;
            double r2 = x * x + y * y + z * z;
            double cos_r = fmax(0.0, (0.6 * x + 0.8 * z) / sqrt(r2)), cos_l = z / sqrt(r2);
            sum += cos_r * cos_l / (M_PI * r2) * (4.0 / (K * K));
        }
    CHECK_NEAR(f, sum, 2e-4);
}

static void test_triangle_source(void) {
    /* Two triangles of a rectangle add up to the rectangle, whatever the vertex order. */
    pn_dvec3 m = pn_dv3(0.3, -0.2, 0);
    pn_contour_source t1, t2;
    pn_contour_source_triangle(&t1, v3(0, 0, 1), v3(2, 0, 1), v3(2, 1, 1), v3(0, 0, -1), false);
    pn_contour_source_triangle(&t2, v3(0, 0, 1), v3(0, 1, 1), v3(2, 1, 1), v3(0, 0, -1), false);
    pn_contour_g g1, g2;
    pn_contour_source_unoccluded(&t1, m, N_UP, N_UP, false, &g1);
    pn_contour_source_unoccluded(&t2, m, N_UP, N_UP, false, &g2);
    double f = pn_dv3_dot(g1.g, N_UP) + pn_dv3_dot(g2.g, N_UP);
    CHECK(pn_dv3_dot(g1.g, N_UP) > 0.0 && pn_dv3_dot(g2.g, N_UP) > 0.0);
    CHECK_NEAR(f, rect_ff_at(m, N_UP, 0, 2, 0, 1, 1), 1e-12);
    /* The unit-square parametrisation covers the triangle: corners map to its vertices. */
    pn_dvec3 c = pn_contour_source_point(&t1, 1, 1);
    CHECK_NEAR(c.x, 2, 1e-12);
    CHECK_NEAR(c.y, 1, 1e-12);
    c = pn_contour_source_point(&t1, 0, 0.7);
    CHECK_NEAR(c.x, 0, 1e-12);
}

/* F of the rectangle source above M minus the part hidden behind a half-plane occluder
 * y <= yo at height zo (parallel to the source): the visible part of the source is bounded by
 * the occluder edge projected from M. The contour is given with the occluder's 3D edge points
 * (Fig. 5) where the silhouette is. */
typedef struct occluded_config {
    double x0, x1, y0, y1, h; /* source */
    double xe0, xe1, yo, zo;  /* occluder edge from (xe0, yo, zo) to (xe1, yo, zo) */
} occluded_config;

/* The visible part as a polygon relative to M; with obstacle points for the silhouette. */
static int visible_polygon(const occluded_config *c, pn_dvec3 m, bool obstacle_points, pn_dvec3 *v) {
    /* Project the edge line y = yo, z = zo from M onto the plane z = h. */
    double t = (c->h - m.z) / (c->zo - m.z);
    double yp = m.y + (c->yo - m.y) * t;
    /* Occluder covers y <= yo below; seen from M it hides source points with y <= yp. */
    double ys = fmax(c->y0, fmin(c->y1, yp));
    /* Visible rectangle [x0, x1] x [ys, y1], counter-clockwise about +z (M below). */
    pn_dvec3 p[4] = {{c->x0, ys, c->h}, {c->x1, ys, c->h}, {c->x1, c->y1, c->h}, {c->x0, c->y1, c->h}};
    if (obstacle_points) {
        /* Points on the occluder whose projection from M are p[0], p[1]. */
        double s = (c->zo - m.z) / (c->h - m.z);
        for (int i = 0; i < 2; i++) p[i] = pn_dv3_add(m, pn_dv3_scale(pn_dv3_sub(p[i], m), s));
    }
    for (int i = 0; i < 4; i++) v[i] = pn_dv3_sub(p[i], m);
    return 4;
}

static pn_contour_g occluded_g(const occluded_config *c, pn_dvec3 m, bool obstacle_points) {
    pn_dvec3 v[4];
    int n = visible_polygon(c, m, obstacle_points, v);
    pn_contour_g g = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    if (!obstacle_points) {
        pn_contour_add_polygon(&g, v, n, N_UP, N_UP, 1.0, true);
        return g;
    }
    /* v[0], v[1] are on the occluder's edge; the visible border pieces end where the edge's
     * projection crosses the source border (x = x0 and x = x1), which slides along y. */
    pn_dvec3 ds = pn_dv3(1, 0, 0), ty = pn_dv3(0, 1, 0);
    pn_dvec3 q0 = pn_dv3(c->x0, 0, c->h), q1 = pn_dv3(c->x1, 0, c->h);
    double t = (c->h - m.z) / (c->zo - m.z);
    q0.y = q1.y = m.y + (c->yo - m.y) * t;
    pn_dvec3 i0 = pn_dv3_add(m, v[0]), vq0[3], vq1[3];
    pn_contour_border_velocity(q0, ty, i0, ds, m, vq0);
    pn_contour_border_velocity(q1, ty, i0, ds, m, vq1);
    pn_dvec3 a0 = pn_dv3_sub(q0, m), a1 = pn_dv3_sub(q1, m);
    pn_contour_add_segment(&g, v[0], v[1], true);               /* silhouette, fixed 3D points */
    pn_contour_add_segment_moving(&g, v[1], a1, NULL, vq1, true); /* along the ray from M: nothing */
    pn_contour_add_segment_moving(&g, a1, v[2], vq1, NULL, true); /* border, sliding end */
    pn_contour_add_segment(&g, v[2], v[3], true);
    pn_contour_add_segment_moving(&g, v[3], a0, NULL, vq0, true);
    pn_contour_add_segment_moving(&g, a0, v[0], vq0, NULL, true);
    return g;
}

/* The same contour with every point fixed (the appendix as written). */
static pn_contour_g occluded_g_fixed(const occluded_config *c, pn_dvec3 m) {
    pn_dvec3 v[4];
    int n = visible_polygon(c, m, true, v);
    pn_contour_g g = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    pn_contour_add_polygon(&g, v, n, N_UP, N_UP, 1.0, true);
    return g;
}

static void test_gradient_matches_finite_differences(void) {
    const occluded_config cfg = {-1, 1, -1, 1, 2, -5, 5, 0.1, 1.0};
    const pn_dvec3 points[] = {{0.2, -0.3, 0}, {-0.4, 0.5, 0.1}, {0.7, 0.05, -0.2}};
    const double h = 1e-5;
    for (size_t i = 0; i < sizeof points / sizeof points[0]; i++) {
        pn_dvec3 m = points[i];
        /* The occluded configuration: silhouette points on the obstacle give the true gradient. */
        pn_contour_g g = occluded_g(&cfg, m, true);
        pn_contour_g g_src = occluded_g(&cfg, m, false);
        /* Same G from either set of points (only directions matter in eq. 4). */
        CHECK_NEAR(pn_dv3_dot(g.g, N_UP), pn_dv3_dot(g_src.g, N_UP), 1e-12);
        double wrong = 0.0;
        for (int k = 0; k < 3; k++) {
            pn_dvec3 e = pn_dv3(k == 0, k == 1, k == 2);
            pn_dvec3 mp = pn_dv3_add(m, pn_dv3_scale(e, h)), mm = pn_dv3_sub(m, pn_dv3_scale(e, h));
            double fp = pn_dv3_dot(occluded_g(&cfg, mp, false).g, N_UP);
            double fm = pn_dv3_dot(occluded_g(&cfg, mm, false).g, N_UP);
            double fd = (fp - fm) / (2 * h);
            CHECK_NEAR(pn_dv3_dot(g.dg[k], N_UP), fd, 1e-6);
            wrong = fmax(wrong, fabs(pn_dv3_dot(g_src.dg[k], N_UP) - fd));
        }
        /* Using the points on the source instead (Fig. 5's warning) gives a different answer,
         * and so does ignoring the sliding of border crossings. */
        CHECK(wrong > 1e-3);
        pn_contour_g gf = occluded_g_fixed(&cfg, m);
        CHECK(fabs(pn_dv3_dot(gf.dg[0], N_UP) - pn_dv3_dot(g.dg[0], N_UP)) > 1e-3);
        /* Unoccluded source: derivatives of eq. 4 with fixed corners. */
        pn_contour_source s;
        pn_contour_source_rectangle(&s, v3(-1, -1, 2), v3(2, 0, 0), v3(0, 2, 0), v3(0, 0, -1), false);
        pn_dvec3 n = pn_dv3(0.3, 0.1, 0.9);
        n = pn_dv3_scale(n, 1.0 / pn_dv3_length(n));
        pn_contour_g u;
        pn_contour_source_unoccluded(&s, m, n, n, true, &u);
        for (int k = 0; k < 3; k++) {
            pn_dvec3 e = pn_dv3(k == 0, k == 1, k == 2);
            pn_contour_g up, um;
            pn_contour_source_unoccluded(&s, pn_dv3_add(m, pn_dv3_scale(e, h)), n, n, false, &up);
            pn_contour_source_unoccluded(&s, pn_dv3_sub(m, pn_dv3_scale(e, h)), n, n, false, &um);
            double fd = (pn_dv3_dot(up.g, n) - pn_dv3_dot(um.g, n)) / (2 * h);
            CHECK_NEAR(pn_dv3_dot(u.dg[k], n), fd, 1e-6);
        }
    }
}

static void test_strip_threshold(void) {
    /* A strip of width eps along a 1 m segment straight above at distance 1: about eps/pi. */
    double t = pn_contour_strip_threshold(pn_dv3(-0.5, 0, 1), pn_dv3(0.5, 0, 1), 1e-3, N_UP, N_UP);
    CHECK_NEAR(t, 1e-3 / M_PI, 1e-6);
    /* Halving the segment halves it (the paper's "threshold divided by two"). */
    double t2 = pn_contour_strip_threshold(pn_dv3(-0.25, 0, 1), pn_dv3(0.25, 0, 1), 1e-3, N_UP, N_UP);
    CHECK_NEAR(t2, t / 2, 1e-7);
}

PN_TESTS(TEST(test_rectangle_matches_closed_form), TEST(test_horizon_clipping), TEST(test_triangle_source),
         TEST(test_gradient_matches_finite_differences), TEST(test_strip_threshold))
