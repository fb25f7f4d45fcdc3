/* test_light_sampling.c — goodness-of-fit tests for pn_light_sample_point.
 *
 * For each light kind the samples drawn from a receiver are sorted into bins (parametric
 * coordinates on planar lights, (1 - cos theta, phi) around the cone axis for spheres, texels
 * and direction cells for environment maps), and the counts are compared with the mass the
 * sampling technique claims for each bin, computed here independently of the library:
 *   uniform area      -> area fraction of the bin,
 *   solid angle       -> solid angle of the bin's piece of the light / solid angle of the light,
 *   environment maps  -> channel-mean weight of each texel times its solid angle.
 * The comparison is Pearson's chi-square test (bins with expected count < 5 pooled) against the
 * critical value at p = 0.001. Random numbers come from a fixed-seed PCG32 stream, so the
 * outcome is deterministic. Each sample is also checked for consistency: positive finite pdf
 * equal to the technique's density, unit wi, finite radiance / pdf, and the point at distance
 * dist along wi lying on the light. Spot lights (delta) are checked for the smoothstep falloff,
 * and environment maps for an unbiased irradiance estimate against quadrature over texels and
 * for samples drawn right at the jumps of their sampling CDF, where rounding can move a sample
 * into the neighbouring texel (those checks currently fail: see env_edge_consistency). */
#include "harness.h"

#include "core/rng.h"
#include "core/sampling.h"
#include "core/sobol.h"
#include "lights/lights.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"

#include <stdbool.h>
#include <stdint.h>
#include <unistd.h>

/* Overridable for longer runs when investigating a near miss; the default run is fixed. */
#ifndef N_SAMPLES
#define N_SAMPLES 100000
#endif
#ifndef SEED_SALT
#define SEED_SALT 0u
#endif
#define GRID 16
#define PI_D 3.14159265358979323846

/* ---- double-precision vectors ---------------------------------------------------------------- */

typedef struct dv {
    double x, y, z;
} dv;

static dv dv3(double x, double y, double z) {
    return (dv){x, y, z};
}
static dv dvf(vec3 a) {
    return dv3((double)a.x, (double)a.y, (double)a.z);
}
static vec3 fv(dv a) {
    return v3((float)a.x, (float)a.y, (float)a.z);
}
static dv dv_add(dv a, dv b) {
    return dv3(a.x + b.x, a.y + b.y, a.z + b.z);
}
static dv dv_sub(dv a, dv b) {
    return dv3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static dv dv_scale(dv a, double s) {
    return dv3(a.x * s, a.y * s, a.z * s);
}
static double dv_dot(dv a, dv b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static dv dv_cross(dv a, dv b) {
    return dv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static double dv_len(dv a) {
    return sqrt(dv_dot(a, a));
}
static dv dv_norm(dv a) {
    return dv_scale(a, 1.0 / dv_len(a));
}

/* Some unit vector perpendicular to unit n, and the third axis n x t. */
static void dv_frame(dv n, dv *t, dv *b) {
    dv a = fabs(n.x) < 0.6 ? dv3(1, 0, 0) : dv3(0, 1, 0);
    *t = dv_norm(dv_cross(a, n));
    *b = dv_cross(n, *t);
}

/* Solid angle of triangle (a, b, c) seen from the origin (Van Oosterom and Strackee 1983). */
static double tri_solid_angle(dv a, dv b, dv c) {
    double la = dv_len(a), lb = dv_len(b), lc = dv_len(c);
    double num = fabs(dv_dot(a, dv_cross(b, c)));
    double den = la * lb * lc + dv_dot(a, b) * lc + dv_dot(a, c) * lb + dv_dot(b, c) * la;
    return 2.0 * atan2(num, den);
}

/* Solid angle from p of the parallelogram corner + [0,1] e1 + [0,1] e2. */
static double quad_solid_angle(dv p, dv corner, dv e1, dv e2) {
    dv c0 = dv_sub(corner, p);
    dv c1 = dv_add(c0, e1), c3 = dv_add(c0, e2), c2 = dv_add(c1, e2);
    return tri_solid_angle(c0, c1, c2) + tri_solid_angle(c0, c2, c3);
}

/* ---- chi-square --------------------------------------------------------------------------- */

/* Regularised upper incomplete gamma function Q(a, x) (series / continued fraction). */
static double gamma_q(double a, double x) {
    if (x <= 0.0) return 1.0;
    double gln = lgamma(a);
    if (x < a + 1.0) {
        double ap = a, sum = 1.0 / a, del = sum;
        for (int n = 0; n < 100000; n++) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if (fabs(del) < fabs(sum) * 1e-15) break;
        }
        return 1.0 - sum * exp(-x + a * log(x) - gln);
    }
    double b = x + 1.0 - a, c = 1.0 / 1e-300, d = 1.0 / b, h = d;
    for (int i = 1; i < 100000; i++) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (fabs(d) < 1e-300) d = 1e-300;
        c = b + an / c;
        if (fabs(c) < 1e-300) c = 1e-300;
        d = 1.0 / d;
        double del = d * c;
        h *= del;
        if (fabs(del - 1.0) < 1e-15) break;
    }
    return exp(-x + a * log(x) - gln) * h;
}

/* The x with P(chi2_dof > x) = alpha. */
static double chi2_critical(int dof, double alpha) {
    double lo = 0.0, hi = (double)dof + 50.0 * sqrt(2.0 * (double)dof) + 100.0;
    for (int it = 0; it < 200; it++) {
        double mid = 0.5 * (lo + hi);
        if (gamma_q(0.5 * (double)dof, 0.5 * mid) > alpha)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

typedef struct chi_bin {
    double e, o;
} chi_bin;

static int cmp_chi_bin(const void *a, const void *b) {
    double x = ((const chi_bin *)a)->e, y = ((const chi_bin *)b)->e;
    return x < y ? -1 : (x > y ? 1 : 0);
}

/* Pearson's test of counts obs[0..n) against probabilities prob[0..n) for `total` draws. Bins
 * with expected count below 5 are pooled (in increasing order of expected count) until the
 * pool reaches 5. A count in a bin of zero probability fails outright. Returns true when the
 * fit is accepted at p = 0.001; prints the statistic either way when `verbose`. */
static bool chi2_accepts(const char *label, const double *obs, const double *prob, int n, double total, bool verbose) {
    chi_bin *bins = malloc((size_t)n * sizeof *bins);
    if (!bins) return false;
    int m = 0;
    double psum = 0.0, impossible = 0.0;
    for (int i = 0; i < n; i++) {
        psum += prob[i];
        if (prob[i] > 0.0)
            bins[m++] = (chi_bin){prob[i] * total, obs[i]};
        else
            impossible += obs[i];
    }
    qsort(bins, (size_t)m, sizeof *bins, cmp_chi_bin);
    double stat = 0.0, pe = 0.0, po = 0.0;
    int cells = 0, k = 0;
    while (k < m && (bins[k].e < 5.0 || (pe > 0.0 && pe < 5.0))) {
        pe += bins[k].e;
        po += bins[k].o;
        k++;
    }
    if (pe > 0.0) {
        stat += (po - pe) * (po - pe) / pe;
        cells++;
    }
    for (; k < m; k++) {
        stat += (bins[k].o - bins[k].e) * (bins[k].o - bins[k].e) / bins[k].e;
        cells++;
    }
    free(bins);
    int dof = cells - 1;
    double crit = dof > 0 ? chi2_critical(dof, 1e-3) : 0.0;
    bool ok = dof > 0 && stat <= crit && impossible == 0.0 && fabs(psum - 1.0) < 1e-6;
    if (verbose || !ok)
        fprintf(stderr, "  %-34s chi2 = %8.1f  dof = %4d  crit(p=0.001) = %7.1f  %s%s\n", label, stat, dof, crit,
                ok ? "ok" : "REJECTED", impossible > 0.0 ? " (samples in zero-probability bins)" : "");
    if (fabs(psum - 1.0) >= 1e-6) fprintf(stderr, "  %s: expected probabilities sum to %.9f\n", label, psum);
    return ok;
}

/* ---- per-sample consistency ------------------------------------------------------------- */

typedef struct run_stats {
    long drawn, valid;
    long bad_basic; /* pdf <= 0 or not finite, radiance / pdf not finite, wi not unit, ... */
    long off_light; /* sampled point not on the light */
    long bad_pdf;   /* pdf differs from the technique's density */
    double max_off, max_pdf_rel;
    double inv_pdf_sum, inv_pdf_sum2;
} run_stats;

static void basic_checks(run_stats *st, const pn_light_sample *s, bool finite_dist) {
    bool ok = isfinite(s->pdf) && s->pdf > 0.0f && !s->delta;
    ok = ok && v3_is_finite(s->radiance) && v3_is_finite(v3_scale(s->radiance, 1.0f / s->pdf));
    ok = ok && fabs(dv_len(dvf(s->wi)) - 1.0) <= 1e-5;
    ok = ok && (finite_dist ? (isfinite(s->dist) && s->dist > 0.0f) : isinf(s->dist));
    if (!ok) st->bad_basic++;
}

static void check_pdf(run_stats *st, double got, double want, double rel_tol) {
    double rel = fabs(got - want) / want;
    if (rel > st->max_pdf_rel) st->max_pdf_rel = rel;
    if (!(rel <= rel_tol)) st->bad_pdf++;
}

static void report_stats(const char *label, const run_stats *st, long want_valid) {
    CHECK_MSG(st->valid == want_valid, "%s: %ld of %ld samples valid, expected %ld", label, st->valid, st->drawn,
              want_valid);
    CHECK_MSG(st->bad_basic == 0, "%s: %ld samples with bad pdf / radiance / wi / dist", label, st->bad_basic);
    CHECK_MSG(st->off_light == 0, "%s: %ld sampled points off the light (max error %.3g)", label, st->off_light,
              st->max_off);
    CHECK_MSG(st->bad_pdf == 0, "%s: %ld pdfs differ from the technique's density (max rel. error %.3g)", label,
              st->bad_pdf, st->max_pdf_rel);
}

/* E[1/pdf] over the samples must be the solid angle covered by the sampler. */
static void check_solid_angle(const char *label, const run_stats *st, double omega) {
    double n = (double)st->drawn;
    double mean = st->inv_pdf_sum / n;
    double var = fmax(0.0, st->inv_pdf_sum2 / n - mean * mean);
    double se = sqrt(var / n);
    CHECK_MSG(fabs(mean - omega) <= 4.5 * se + 1e-5 * omega, "%s: E[1/pdf] = %.7g, solid angle %.7g (se %.2g)", label,
              mean, omega, se);
}

static pn_lights one_light(pn_light *l) {
    pn_lights L;
    memset(&L, 0, sizeof L);
    L.lights = l;
    L.count = 1;
    L.scene_radius = 10.0f;
    return L;
}

static pn_light blank_light(pn_light_kind kind) {
    pn_light l;
    memset(&l, 0, sizeof l);
    l.kind = kind;
    l.emit = v3(1.5f, 2.0f, 2.5f);
    l.env = -1;
    l.mesh = -1;
    l.prim = -1;
    return l;
}

/* Every sampling run gets its own fixed stream, derived from its label (FNV-1a), so runs that bin
 * the same warp from different receivers do not repeat one another's counts, and adding a case
 * leaves the others' streams alone. */
static void seed_run(pn_rng *rng, const char *label) {
    uint64_t h = UINT64_C(0xcbf29ce484222325);
    for (const char *c = label; *c; c++) h = (h ^ (uint64_t)(unsigned char)*c) * UINT64_C(0x100000001b3);
    pn_rng_seed(rng, h + SEED_SALT, 0x5eedu);
}

static void draw(pn_rng *rng, float *u1, float *u2) {
    *u1 = pn_rng_float(rng);
    *u2 = pn_rng_float(rng);
}

/* ---- planar lights: triangle, rectangle, disk ---------------------------------------------- */

typedef enum planar_pdf { PDF_AREA, PDF_SOLID_ANGLE } planar_pdf;

/* Samples planar light l from p, bins the sampled points in a GRID x GRID table of parametric
 * coordinates (triangle: (b1, b2) along e1, e2; rectangle: (a, b) along e1, e2; disk: (r^2/R^2,
 * phi / 2 pi)), and runs the chi-square test against the technique's bin masses. `visible`:
 * whether p is on a side from which the light is sampled at all. */
static void run_planar(const char *label, pn_light l, vec3 pf, planar_pdf technique, bool visible) {
    pn_lights L = one_light(&l);
    dv p = dvf(pf), p0 = dvf(l.p), e1 = dvf(l.e1), e2 = dvf(l.e2), n = dvf(l.n);
    dv ta, tb;
    dv_frame(n, &ta, &tb);
    double R = (double)l.radius;
    double area;
    if (l.kind == PN_LIGHT_TRIANGLE)
        area = 0.5 * dv_len(dv_cross(e1, e2));
    else if (l.kind == PN_LIGHT_RECTANGLE)
        area = dv_len(dv_cross(e1, e2));
    else
        area = PI_D * R * R;
    double size = l.kind == PN_LIGHT_DISK ? 2.0 * R : dv_len(e1) + dv_len(e2);
    double g11 = dv_dot(e1, e1), g12 = dv_dot(e1, e2), g22 = dv_dot(e2, e2), det = g11 * g22 - g12 * g12;

    /* Solid angle of the light from p, and (rectangle, solid-angle technique) of each cell. */
    static double prob[GRID * GRID], obs[GRID * GRID];
    double omega = 0.0;
    if (l.kind == PN_LIGHT_TRIANGLE) {
        omega = tri_solid_angle(dv_sub(p0, p), dv_sub(dv_add(p0, e1), p), dv_sub(dv_add(p0, e2), p));
        for (int j = 0; j < GRID; j++)
            for (int i = 0; i < GRID; i++)
                prob[j * GRID + i] =
                    i + j < GRID - 1 ? 2.0 / (GRID * GRID) : (i + j == GRID - 1 ? 1.0 / (GRID * GRID) : 0.0);
    } else if (l.kind == PN_LIGHT_RECTANGLE) {
        omega = quad_solid_angle(p, p0, e1, e2);
        for (int j = 0; j < GRID; j++)
            for (int i = 0; i < GRID; i++) {
                if (technique == PDF_AREA) {
                    prob[j * GRID + i] = 1.0 / (GRID * GRID);
                    continue;
                }
                dv c = dv_add(p0, dv_add(dv_scale(e1, (double)i / GRID), dv_scale(e2, (double)j / GRID)));
                prob[j * GRID + i] = quad_solid_angle(p, c, dv_scale(e1, 1.0 / GRID), dv_scale(e2, 1.0 / GRID)) / omega;
            }
    } else {
        /* Disk: cos / d^2 over the area, midpoint rule in (r^2, phi). */
        const int S = 500;
        for (int a = 0; a < S; a++)
            for (int b = 0; b < S; b++) {
                double r = R * sqrt((a + 0.5) / S), phi = 2.0 * PI_D * (b + 0.5) / S;
                dv y = dv_add(p0, dv_add(dv_scale(ta, r * cos(phi)), dv_scale(tb, r * sin(phi))));
                dv d = dv_sub(y, p);
                double d2 = dv_dot(d, d);
                omega += fabs(dv_dot(d, n)) / (d2 * sqrt(d2));
            }
        omega *= area / ((double)S * S);
        for (int i = 0; i < GRID * GRID; i++) prob[i] = 1.0 / (GRID * GRID);
    }
    memset(obs, 0, sizeof obs);

    run_stats st;
    memset(&st, 0, sizeof st);
    pn_rng rng;
    seed_run(&rng, label);
    for (long k = 0; k < N_SAMPLES; k++) {
        float u1, u2;
        draw(&rng, &u1, &u2);
        pn_light_sample s;
        st.drawn++;
        if (!pn_light_sample_point(&L, &l, pf, u1, u2, &s)) continue;
        st.valid++;
        basic_checks(&st, &s, true);
        dv wi = dvf(s.wi);
        double dist = (double)s.dist;
        dv y = dv_add(p, dv_scale(wi, dist));
        dv q = dv_sub(y, p0);
        double tol = 2e-6 * (dv_len(dv_sub(p0, p)) + size) + 1e-7;

        /* On the light: in its plane and inside its outline. */
        double off = fabs(dv_dot(q, n));
        double c1, c2;
        int cell;
        if (l.kind == PN_LIGHT_DISK) {
            double x = dv_dot(q, ta), z = dv_dot(q, tb);
            double rr = sqrt(x * x + z * z);
            off = fmax(off, rr - R);
            c1 = fmin(rr * rr / (R * R), 1.0 - 1e-12);
            double phi = atan2(z, x);
            if (phi < 0.0) phi += 2.0 * PI_D;
            c2 = fmin(phi / (2.0 * PI_D), 1.0 - 1e-12);
        } else {
            double r1 = dv_dot(q, e1), r2 = dv_dot(q, e2);
            c1 = (g22 * r1 - g12 * r2) / det;
            c2 = (g11 * r2 - g12 * r1) / det;
            double lim = l.kind == PN_LIGHT_TRIANGLE ? c1 + c2 : fmax(c1, c2);
            off = fmax(off, fmax(fmax(-c1, -c2), lim - 1.0) * size);
            c1 = fmax(c1, 0.0);
            c2 = fmax(c2, 0.0);
            if (l.kind == PN_LIGHT_TRIANGLE) {
                if (c1 + c2 >= 1.0) {
                    double sc = (1.0 - 1e-12) / (c1 + c2);
                    c1 *= sc;
                    c2 *= sc;
                }
            } else {
                c1 = fmin(c1, 1.0 - 1e-12);
                c2 = fmin(c2, 1.0 - 1e-12);
            }
        }
        if (off > st.max_off) st.max_off = off;
        if (off > tol) st.off_light++;
        cell = (int)(c2 * GRID) * GRID + (int)(c1 * GRID);
        obs[cell] += 1.0;

        double cos_l = fabs(dv_dot(wi, n));
        double want = technique == PDF_SOLID_ANGLE ? 1.0 / omega : dist * dist / (area * cos_l);
        check_pdf(&st, (double)s.pdf, want, technique == PDF_SOLID_ANGLE ? 1e-4 : 2e-3);
        /* Radiance is the light's, unchanged. */
        if (s.radiance.x != l.emit.x || s.radiance.y != l.emit.y || s.radiance.z != l.emit.z) st.bad_basic++;
        double ip = 1.0 / (double)s.pdf;
        st.inv_pdf_sum += ip;
        st.inv_pdf_sum2 += ip * ip;
    }
    report_stats(label, &st, visible ? N_SAMPLES : 0);
    if (!visible) return;
    CHECK_MSG(chi2_accepts(label, obs, prob, GRID * GRID, (double)N_SAMPLES, true), "%s: distribution", label);
    check_solid_angle(label, &st, omega);
}

static pn_light triangle_light(dv p0, dv e1, dv e2, bool two_sided) {
    pn_light l = blank_light(PN_LIGHT_TRIANGLE);
    l.p = fv(p0);
    l.e1 = fv(e1);
    l.e2 = fv(e2);
    l.n = fv(dv_norm(dv_cross(e1, e2)));
    l.area = (float)(0.5 * dv_len(dv_cross(e1, e2)));
    l.two_sided = two_sided;
    return l;
}

/* A w x h rectangle centred at c with emitting normal n (edges e1, e2 with e1 x e2 along n). */
static pn_light rectangle_light(dv c, dv n, double w, double h, bool two_sided) {
    dv t, b;
    n = dv_norm(n);
    dv_frame(n, &t, &b); /* t x b = n */
    pn_light l = blank_light(PN_LIGHT_RECTANGLE);
    l.p = fv(dv_sub(c, dv_add(dv_scale(t, 0.5 * w), dv_scale(b, 0.5 * h))));
    l.e1 = fv(dv_scale(t, w));
    l.e2 = fv(dv_scale(b, h));
    l.n = fv(n);
    l.area = (float)(w * h);
    l.two_sided = two_sided;
    return l;
}

static pn_light disk_light(dv c, dv n, double r, bool two_sided) {
    pn_light l = blank_light(PN_LIGHT_DISK);
    l.p = fv(c);
    l.n = fv(dv_norm(n));
    l.radius = (float)r;
    l.area = (float)(PI_D * r * r);
    l.two_sided = two_sided;
    return l;
}

static void test_triangle_light(void) {
    dv p0 = dv3(0.1, -0.3, 1.0), e1 = dv3(1.2, 0.2, 0.1), e2 = dv3(0.2, 0.9, -0.2);
    dv n = dv_norm(dv_cross(e1, e2));
    dv centroid = dv_add(p0, dv_scale(dv_add(e1, e2), 1.0 / 3.0));
    pn_light l = triangle_light(p0, e1, e2, false);
    run_planar("triangle, in front", l, fv(dv_add(centroid, dv_add(dv_scale(n, 0.6), dv3(0.2, 0.1, 0.0)))), PDF_AREA,
               true);
    /* Close to the surface, above a point near a corner. */
    dv near = dv_add(p0, dv_add(dv_scale(e1, 0.3), dv_scale(e2, 0.2)));
    run_planar("triangle, close", l, fv(dv_add(near, dv_scale(n, 0.03))), PDF_AREA, true);
    /* Grazing: well off to the side, slightly in front of the plane. */
    run_planar("triangle, grazing", l, fv(dv_add(centroid, dv_add(dv_scale(e1, 1.5), dv_scale(n, 0.15)))), PDF_AREA,
               true);
    pn_light l2 = triangle_light(p0, e1, e2, true);
    run_planar("triangle, two-sided from behind", l2, fv(dv_sub(centroid, dv_scale(n, 0.4))), PDF_AREA, true);
    run_planar("triangle, one-sided from behind", l, fv(dv_sub(centroid, dv_scale(n, 0.4))), PDF_AREA, false);
}

static void test_rectangle_light(void) {
    /* A unit square 5 cm above the receiver: solid-angle sampling concentrates the samples in
     * the cells right above it. */
    pn_light close = rectangle_light(dv3(0, 0, 0.05), dv3(0, 0, -1), 1.0, 1.0, false);
    run_planar("rectangle, close", close, v3(0.1f, -0.15f, 0.0f), PDF_SOLID_ANGLE, true);
    /* A tilted 2 x 0.6 rectangle seen at about 6 degrees elevation from 2.5 m to the side. */
    dv c = dv3(0.3, -0.2, 1.0), n = dv_norm(dv3(0.2, -0.1, -1.0));
    pn_light obl = rectangle_light(c, n, 2.0, 0.6, false);
    dv t, b;
    dv_frame(n, &t, &b);
    run_planar("rectangle, oblique", obl, fv(dv_add(c, dv_add(dv_scale(t, 2.5), dv_scale(n, 0.25)))), PDF_SOLID_ANGLE,
               true);
    /* Oblique and close: just in front of the plane, beside one edge. */
    run_planar("rectangle, oblique and close", obl, fv(dv_add(c, dv_add(dv_scale(t, 1.1), dv_scale(n, 0.02)))),
               PDF_SOLID_ANGLE, true);
    pn_light back = rectangle_light(dv3(0, 0, 0.7), dv3(0, 0, -1), 1.2, 0.8, true);
    run_planar("rectangle, two-sided from behind", back, v3(0.2f, 0.1f, 1.0f), PDF_SOLID_ANGLE, true);
    back.two_sided = false;
    run_planar("rectangle, one-sided from behind", back, v3(0.2f, 0.1f, 1.0f), PDF_SOLID_ANGLE, false);
    /* 1 cm square 20 m away: its solid angle (2.5e-7 sr) is below the threshold for spherical
     * rectangle sampling, so the sampler falls back to uniform area sampling. */
    pn_light tiny = rectangle_light(dv3(0, 0, 20.0), dv3(0, 0, -1), 0.01, 0.01, false);
    run_planar("rectangle, tiny and far (area)", tiny, v3(0.3f, -0.2f, 0.0f), PDF_AREA, true);
}

static void test_disk_light(void) {
    run_planar("disk, facing", disk_light(dv3(0, 0, 1.5), dv3(0, 0, -1), 0.8, false), v3(0, 0, 0), PDF_AREA, true);
    dv c = dv3(0.3, 0.2, 1.0), n = dv_norm(dv3(-0.5, 0.3, -1.0));
    dv t, b;
    dv_frame(n, &t, &b);
    run_planar("disk, oblique", disk_light(c, n, 0.5, false), fv(dv_add(c, dv_add(dv_scale(t, 1.2), dv_scale(n, 0.3)))),
               PDF_AREA, true);
    run_planar("disk, two-sided from behind", disk_light(dv3(0, 0, 1), dv3(0, 0, -1), 0.6, true), v3(0.2f, 0.0f, 1.4f),
               PDF_AREA, true);
    run_planar("disk, one-sided from behind", disk_light(dv3(0, 0, 1), dv3(0, 0, -1), 0.6, false), v3(0.2f, 0.0f, 1.4f),
               PDF_AREA, false);
}

/* The disk's solid angle by quadrature (used above for E[1/pdf]) against the on-axis closed
 * form, so that the reference itself is trustworthy. */
static void test_disk_reference_solid_angle(void) {
    double h = 1.5, R = 0.8, S = 500;
    double omega = 0.0;
    for (int a = 0; a < (int)S; a++) {
        double r = R * sqrt((a + 0.5) / S);
        omega += h / pow(h * h + r * r, 1.5);
    }
    omega *= PI_D * R * R / S;
    CHECK_NEAR(omega, 2.0 * PI_D * (1.0 - h / sqrt(h * h + R * R)), 1e-6);
}

/* ---- spheres ------------------------------------------------------------------------------- */

/* Bins cone samples of sphere (c, r) from p by t = (1 - cos theta) / (1 - cos theta_max) and phi
 * around the axis; uniform sampling of the cone makes every cell equally likely. When
 * `omc_claim` > 0 the cells are laid out for that cone instead (to check the test's power). */
static bool run_sphere(const char *label, dv c, double r, dv p, double omc_claim, bool checks) {
    pn_light l = blank_light(PN_LIGHT_SPHERE);
    l.p = fv(c);
    l.radius = (float)r;
    l.area = (float)(4.0 * PI_D * r * r);
    pn_lights L = one_light(&l);
    dv pc = dv_sub(dvf(l.p), p);
    double d = dv_len(pc), sin2 = (double)l.radius * (double)l.radius / (d * d);
    double omc_max = sin2 / (1.0 + sqrt(1.0 - sin2));
    double omc_bins = omc_claim > 0.0 ? omc_claim : omc_max;
    dv w = dv_scale(pc, 1.0 / d), ta, tb;
    dv_frame(w, &ta, &tb);

    static double prob[GRID * GRID], obs[GRID * GRID];
    for (int i = 0; i < GRID * GRID; i++) {
        prob[i] = 1.0 / (GRID * GRID);
        obs[i] = 0.0;
    }
    run_stats st;
    memset(&st, 0, sizeof st);
    long outside_cone = 0;
    double max_facing = 0.0;
    pn_rng rng;
    seed_run(&rng, label);
    for (long k = 0; k < N_SAMPLES; k++) {
        float u1, u2;
        draw(&rng, &u1, &u2);
        pn_light_sample s;
        st.drawn++;
        if (!pn_light_sample_point(&L, &l, fv(p), u1, u2, &s)) continue;
        st.valid++;
        basic_checks(&st, &s, true);
        dv wi = dvf(s.wi);
        double theta = atan2(dv_len(dv_cross(wi, w)), dv_dot(wi, w));
        double sh = sin(0.5 * theta), omc = 2.0 * sh * sh;
        if (omc > omc_max * (1.0 + 1e-3) + 1e-12) outside_cone++;
        double t = fmin(omc / omc_bins, 1.0 - 1e-12);
        double phi = atan2(dv_dot(wi, tb), dv_dot(wi, ta));
        if (phi < 0.0) phi += 2.0 * PI_D;
        obs[(int)(t * GRID) * GRID + (int)fmin(phi / (2.0 * PI_D) * GRID, GRID - 1)] += 1.0;
        /* The point: on the sphere, on the hemisphere facing the receiver. */
        dv y = dv_add(p, dv_scale(wi, (double)s.dist));
        dv yc = dv_sub(y, dvf(l.p));
        double off = fabs(dv_len(yc) - r);
        if (off > st.max_off) st.max_off = off;
        if (off > 3e-6 * (d + r)) st.off_light++;
        double facing = dv_dot(yc, wi) / r;
        if (facing > max_facing) max_facing = facing;
        check_pdf(&st, (double)s.pdf, 1.0 / (2.0 * PI_D * omc_max), 1e-4);
    }
    if (!checks) return chi2_accepts(label, obs, prob, GRID * GRID, (double)N_SAMPLES, false);
    report_stats(label, &st, N_SAMPLES);
    CHECK_MSG(outside_cone == 0, "%s: %ld directions outside the cone", label, outside_cone);
    /* Nearest intersection: the sphere's normal at the point faces the receiver (up to
     * rounding at the silhouette). */
    CHECK_MSG(max_facing < 2e-3, "%s: sampled point on the far side (n.wi = %.3g)", label, max_facing);
    bool ok = chi2_accepts(label, obs, prob, GRID * GRID, (double)N_SAMPLES, true);
    CHECK_MSG(ok, "%s: distribution", label);
    return ok;
}

static void test_sphere_light(void) {
    dv c = dv3(0.3, -0.2, 1.0);
    dv dir = dv_norm(dv3(0.3, 0.5, -1.0));
    run_sphere("sphere, close (d = 1.2 r)", c, 0.8, dv_add(c, dv_scale(dir, 0.96)), 0.0, true);
    run_sphere("sphere, medium (d = 3 r)", c, 0.8, dv_add(c, dv_scale(dir, 2.4)), 0.0, true);
    run_sphere("sphere, far (d = 100 r)", c, 0.5, dv_add(c, dv_scale(dir, 50.0)), 0.0, true);
    /* Inside the sphere nothing is sampled. */
    pn_light l = blank_light(PN_LIGHT_SPHERE);
    l.p = fv(c);
    l.radius = 0.8f;
    l.area = (float)(4.0 * PI_D * 0.64);
    pn_lights L = one_light(&l);
    pn_light_sample s;
    CHECK(!pn_light_sample_point(&L, &l, fv(dv_add(c, dv3(0.1, 0.2, 0.3))), 0.3f, 0.6f, &s));
}

/* The chi-square machinery: critical values against tables, and power to reject a sampler
 * whose cone is 3 % narrower (in 1 - cos theta) than the density claimed. */
static void test_chi2_machinery(void) {
    CHECK_NEAR(chi2_critical(1, 1e-3), 10.828, 2e-3);
    CHECK_NEAR(chi2_critical(10, 1e-3), 29.588, 2e-3);
    CHECK_NEAR(chi2_critical(100, 1e-3), 149.449, 2e-3);
    CHECK_NEAR(chi2_critical(255, 1e-3), 330.5, 1.0);
    dv c = dv3(0.3, -0.2, 1.0), p = dv_add(c, dv3(0.0, 0.0, -0.96));
    double sin2 = 0.64 / (0.96 * 0.96), omc = sin2 / (1.0 + sqrt(1.0 - sin2));
    CHECK(!run_sphere("sphere vs. a 3% wider cone", c, 0.8, p, 1.03 * omc, false));
    /* A close rectangle's solid-angle samples are far from uniform over its area. */
    static double obs[GRID * GRID], prob[GRID * GRID];
    memset(obs, 0, sizeof obs);
    pn_light l = rectangle_light(dv3(0, 0, 0.3), dv3(0, 0, -1), 1.0, 1.0, false);
    pn_lights L = one_light(&l);
    pn_rng rng;
    pn_rng_seed(&rng, 99u, 1u);
    for (int k = 0; k < N_SAMPLES; k++) {
        float u1, u2;
        draw(&rng, &u1, &u2);
        pn_light_sample s;
        if (!pn_light_sample_point(&L, &l, v3(0, 0, 0), u1, u2, &s)) continue;
        dv q = dv_sub(dv_scale(dvf(s.wi), (double)s.dist), dvf(l.p));
        double a = fmin(fmax(dv_dot(q, dvf(l.e1)) / (double)v3_length2(l.e1), 0.0), 1.0 - 1e-12);
        double b = fmin(fmax(dv_dot(q, dvf(l.e2)) / (double)v3_length2(l.e2), 0.0), 1.0 - 1e-12);
        obs[(int)(b * GRID) * GRID + (int)(a * GRID)] += 1.0;
    }
    for (int i = 0; i < GRID * GRID; i++) prob[i] = 1.0 / (GRID * GRID);
    CHECK(!chi2_accepts("rectangle vs. uniform area", obs, prob, GRID * GRID, N_SAMPLES, false));
}

/* ---- point, spot and distant lights -------------------------------------------------------- */

static double smoothstep_falloff(double cos_theta, double cos_total, double cos_start) {
    if (cos_theta >= cos_start) return 1.0;
    if (cos_theta <= cos_total) return 0.0;
    double t = (cos_theta - cos_total) / (cos_start - cos_total);
    return t * t * (3.0 - 2.0 * t);
}

static void test_spot_falloff(void) {
    pn_light l = blank_light(PN_LIGHT_SPOT);
    dv pos = dv3(0.2, -0.1, 2.0), axis = dv_norm(dv3(0.1, 0.2, -1.0));
    l.p = fv(pos);
    l.n = fv(axis);
    l.emit = v3(4.0f, 3.0f, 2.0f);
    double cos_total = cos(30.0 * PI_D / 180.0), cos_start = cos(22.0 * PI_D / 180.0);
    l.cos_total_width = (float)cos_total;
    l.cos_falloff_start = (float)cos_start;
    pn_lights L = one_light(&l);
    dv t, b;
    dv_frame(axis, &t, &b);
    int bad_value = 0, bad_presence = 0, bad_geometry = 0, bad_estimate = 0, in_band = 0;
    double max_rel = 0.0;
    const double azimuths[4] = {0.0, 1.3, 2.9, 4.4}, dists[2] = {0.7, 2.3};
    for (int ia = 0; ia <= 160; ia++) {
        double alpha = (double)ia * 0.25 * PI_D / 180.0;
        for (int iz = 0; iz < 4; iz++)
            for (int id = 0; id < 2; id++) {
                dv dir = dv_add(
                    dv_scale(axis, cos(alpha)),
                    dv_scale(dv_add(dv_scale(t, cos(azimuths[iz])), dv_scale(b, sin(azimuths[iz]))), sin(alpha)));
                vec3 p = fv(dv_add(pos, dv_scale(dir, dists[id])));
                /* The falloff the sampler should apply, from the receiver actually used. */
                dv rel = dv_sub(dvf(p), dvf(l.p));
                double D = dv_len(rel), c = dv_dot(dv_scale(rel, 1.0 / D), dvf(l.n));
                double f = smoothstep_falloff(c, (double)l.cos_total_width, (double)l.cos_falloff_start);
                bool edge = fabs(c - (double)l.cos_total_width) < 1e-6;
                pn_light_sample s;
                bool got = pn_light_sample_point(&L, &l, p, 0.5f, 0.5f, &s);
                if (edge) continue;
                if (got != (f > 0.0)) {
                    bad_presence++;
                    continue;
                }
                if (!got) continue;
                if (f > 0.0 && f < 1.0) in_band++;
                if (!s.delta || s.pdf != 1.0f || fabs((double)s.dist - D) > 1e-5 * D ||
                    dv_len(dv_add(dvf(s.wi), dv_scale(rel, 1.0 / D))) > 1e-5)
                    bad_geometry++;
                for (int ch = 0; ch < 3; ch++) {
                    double want = (double)v3_get(l.emit, ch) * f / (D * D);
                    double got_v = (double)v3_get(s.radiance, ch);
                    double err = fabs(got_v - want) / ((double)v3_get(l.emit, ch) / (D * D));
                    if (err > max_rel) max_rel = err;
                    if (err > 2e-5) bad_value++;
                }
                /* The irradiance estimate applies the same falloff. */
                vec3 n = fv(dv_norm(dv_add(dv_scale(rel, -1.0 / D), dv3(0.1, 0.0, 0.0))));
                double cn = dv_dot(dvf(n), dv_scale(rel, -1.0 / D));
                double e_want = (double)v3_luminance(l.emit) * f * cn / (D * D);
                double e_got = (double)pn_light_irradiance_estimate(&L, &l, p, n);
                if (fabs(e_got - e_want) > 1e-4 * (double)v3_luminance(l.emit) / (D * D)) bad_estimate++;
            }
    }
    CHECK(in_band > 100);
    CHECK_MSG(bad_presence == 0, "%d receivers lit / unlit against the cone", bad_presence);
    CHECK_MSG(bad_geometry == 0, "%d samples with wrong wi / dist / pdf / delta", bad_geometry);
    CHECK_MSG(bad_value == 0, "%d radiance values off the smoothstep falloff (max rel. error %.3g)", bad_value,
              max_rel);
    CHECK_MSG(bad_estimate == 0, "%d irradiance estimates off the falloff", bad_estimate);
    /* Half way across the band (in cos theta) the smoothstep is exactly 1/2. */
    double cmid = 0.5 * ((double)l.cos_total_width + (double)l.cos_falloff_start);
    dv dir = dv_add(dv_scale(axis, cmid), dv_scale(t, sqrt(1.0 - cmid * cmid)));
    pn_light_sample s;
    CHECK(pn_light_sample_point(&L, &l, fv(dv_add(pos, dv_scale(dir, 1.0))), 0.1f, 0.9f, &s));
    CHECK_NEAR(s.radiance.x, 0.5 * 4.0, 1e-4);
}

static void test_point_and_distant(void) {
    pn_light pt = blank_light(PN_LIGHT_POINT);
    pt.p = v3(1.0f, 2.0f, 3.0f);
    pt.emit = v3(8.0f, 4.0f, 2.0f);
    pn_lights L = one_light(&pt);
    pn_light_sample s;
    CHECK(pn_light_sample_point(&L, &pt, v3(1.0f, 2.0f, 1.0f), 0.2f, 0.7f, &s));
    CHECK(s.delta && s.pdf == 1.0f);
    CHECK_NEAR(s.dist, 2.0, 1e-6);
    CHECK_NEAR(s.wi.z, 1.0, 1e-6);
    CHECK_NEAR(s.radiance.x, 2.0, 1e-6);
    CHECK_NEAR(s.radiance.z, 0.5, 1e-6);
    pn_light di = blank_light(PN_LIGHT_DISTANT);
    di.n = fv(dv_norm(dv3(0.3, -0.4, 1.0)));
    di.emit = v3(3.0f, 3.0f, 3.0f);
    CHECK(pn_light_sample_point(&L, &di, v3(5, 6, 7), 0.9f, 0.1f, &s));
    CHECK(s.delta && s.pdf == 1.0f && isinf(s.dist));
    CHECK(s.wi.x == di.n.x && s.wi.y == di.n.y && s.wi.z == di.n.z);
    CHECK(s.radiance.y == 3.0f);
}

/* ---- environment maps ---------------------------------------------------------------------- */

static char tmpdir[256];

static void quiet_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static bool write_text(const char *name, const char *text) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "w");
    if (!f) return false;
    fputs(text, f);
    return fclose(f) == 0;
}

/* Writes rgb (row 0 = top of the image) as a PFM file (rows stored bottom to top). */
static bool write_pfm(const char *name, const float *rgb, int w, int h) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    if (!f) return false;
    const uint32_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    fprintf(f, "PF\n%d %d\n%s\n", w, h, first == 1 ? "-1" : "1");
    for (int y = h - 1; y >= 0; y--) fwrite(rgb + (size_t)y * (size_t)w * 3, sizeof(float), (size_t)w * 3, f);
    return fclose(f) == 0;
}

static void remove_file(const char *name) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    unlink(path);
}

/* Light space -> world for "Rotate -90 1 0 0": (x, y, z) -> (x, z, -y), and back. */
static dv light_to_world(dv a) {
    return dv3(a.x, a.z, -a.y);
}
static dv world_to_light(dv a) {
    return dv3(a.x, -a.z, a.y);
}

typedef struct env_case {
    const char *label;
    int w, h;
    bool equal_area;
    float *rgb; /* our copy of the image */
    float scale;
    double *prob; /* per texel: mean-channel weight x solid angle, normalised */
} env_case;

/* Texel of a light-space direction, by our own inversion for lat-long maps. */
static int env_texel_of(const env_case *ec, dv wl) {
    double u, v;
    if (ec->equal_area) {
        float fu, fv_;
        pn_equal_area_sphere_to_square(fv(wl), &fu, &fv_);
        u = (double)fu;
        v = (double)fv_;
    } else {
        double theta = acos(fmax(-1.0, fmin(1.0, wl.z / dv_len(wl))));
        double phi = atan2(wl.y, wl.x);
        if (phi < 0.0) phi += 2.0 * PI_D;
        u = phi / (2.0 * PI_D);
        v = theta / PI_D;
    }
    int x = (int)(u * ec->w), y = (int)(v * ec->h);
    x = x < 0 ? 0 : (x >= ec->w ? ec->w - 1 : x);
    y = y < 0 ? 0 : (y >= ec->h ? ec->h - 1 : y);
    return y * ec->w + x;
}

static void env_compute_prob(env_case *ec) {
    int n = ec->w * ec->h;
    double total = 0.0;
    for (int y = 0; y < ec->h; y++)
        for (int x = 0; x < ec->w; x++) {
            const float *px = ec->rgb + 3 * (y * ec->w + x);
            double mean = ((double)px[0] + (double)px[1] + (double)px[2]) / 3.0 * (double)ec->scale;
            double omega = ec->equal_area
                               ? 4.0 * PI_D / n
                               : (2.0 * PI_D / ec->w) * (cos(PI_D * y / ec->h) - cos(PI_D * (y + 1) / ec->h));
            ec->prob[y * ec->w + x] = mean * omega;
            total += mean * omega;
        }
    for (int i = 0; i < n; i++) ec->prob[i] /= total;
}

/* Solid-angle density the sampler should have at light-space direction wl. */
static double env_density(const env_case *ec, dv wl) {
    int t = env_texel_of(ec, wl);
    double n = (double)(ec->w * ec->h);
    if (ec->equal_area) return ec->prob[t] * n / (4.0 * PI_D);
    double sin_theta = sqrt(wl.x * wl.x + wl.y * wl.y) / dv_len(wl);
    return ec->prob[t] * n / (2.0 * PI_D * PI_D * sin_theta);
}

/* Irradiance at normal n (world) by quadrature over the texels (S x S points each). */
static dv env_quadrature_irradiance(const env_case *ec, dv n) {
    const int S = 24;
    dv sum = dv3(0, 0, 0);
    for (int y = 0; y < ec->h; y++)
        for (int x = 0; x < ec->w; x++) {
            const float *px = ec->rgb + 3 * (y * ec->w + x);
            if (px[0] == 0.0f && px[1] == 0.0f && px[2] == 0.0f) continue;
            double acc = 0.0;
            for (int j = 0; j < S; j++)
                for (int i = 0; i < S; i++) {
                    double u = (x + (i + 0.5) / S) / ec->w, v = (y + (j + 0.5) / S) / ec->h;
                    dv wl;
                    double jac;
                    if (ec->equal_area) {
                        wl = dvf(pn_equal_area_square_to_sphere((float)u, (float)v));
                        jac = 4.0 * PI_D;
                    } else {
                        double th = v * PI_D, ph = u * 2.0 * PI_D;
                        wl = dv3(sin(th) * cos(ph), sin(th) * sin(ph), cos(th));
                        jac = 2.0 * PI_D * PI_D * sin(th);
                    }
                    double c = dv_dot(dv_norm(light_to_world(wl)), n);
                    if (c > 0.0) acc += c * jac;
                }
            acc /= (double)S * S * ec->w * ec->h;
            double sc = (double)ec->scale;
            sum = dv_add(sum, dv3(acc * (double)px[0] * sc, acc * (double)px[1] * sc, acc * (double)px[2] * sc));
        }
    return sum;
}

/* Density the sampler should report for a sample in texel t at light-space direction wl. */
static double env_texel_density(const env_case *ec, int t, dv wl) {
    double n = (double)(ec->w * ec->h);
    if (ec->equal_area) return ec->prob[t] * n / (4.0 * PI_D);
    return ec->prob[t] * n / (2.0 * PI_D * PI_D * sqrt(wl.x * wl.x + wl.y * wl.y) / dv_len(wl));
}

/* True when the sample's radiance and pdf belong to one texel: some texel near the direction
 * has exactly that radiance, and the pdf is that texel's density. */
static bool env_sample_consistent(const env_case *ec, const pn_light_sample *s) {
    dv wl = world_to_light(dvf(s->wi));
    int t0 = env_texel_of(ec, wl), x0 = t0 % ec->w, y0 = t0 / ec->w;
    double sin_theta = sqrt(wl.x * wl.x + wl.y * wl.y);
    double tol = ec->equal_area ? 1e-4 : 1e-3 + 1e-6 / sin_theta;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int x = (x0 + dx + ec->w) % ec->w, y = y0 + dy;
            if (y < 0 || y >= ec->h) continue;
            const float *px = ec->rgb + 3 * (y * ec->w + x);
            vec3 c = v3_scale(v3(px[0], px[1], px[2]), ec->scale);
            if (c.x != s->radiance.x || c.y != s->radiance.y || c.z != s->radiance.z) continue;
            double want = env_texel_density(ec, y * ec->w + x, wl);
            if (fabs((double)s->pdf - want) <= tol * want) return true;
        }
    return false;
}

/* The cell pn_distribution2d chooses for (u1, u2), identified by its uv density. */
static float chosen_cell_key(const pn_env *env, float u1, float u2) {
    float u, v, pdf;
    return pn_distribution2d_sample(env->dist, u1, u2, &u, &v, &pdf) ? pdf : 0.0f;
}

/* Samples drawn with u1 (or u2) on either side of every jump of the sampling CDF, found by
 * bisection down to adjacent floats: the points where rounding can carry a sample across a
 * texel edge. Each must still get the radiance and pdf of one and the same texel. */
static void env_edge_consistency(const env_case *ec, const pn_lights *L, const pn_light *l, const pn_env *env) {
    long tested = 0, inconsistent = 0, dist_mismatch = 0;
    vec3 p = v3(0, 0, 0);
    for (int axis = 0; axis < 2; axis++)
        for (int line = 0; line < 16; line++) {
            float fixed = ((float)line + 0.37f) / 16.0f;
            const int G = 2048;
            float prev_u = 0.0f, prev_key = -1.0f;
            for (int k = 0; k <= G; k++) {
                float u = k == G ? 0x1.fffffep-1f : (float)k / (float)G;
                float key = chosen_cell_key(env, axis ? fixed : u, axis ? u : fixed);
                if (k > 0 && key != prev_key) {
                    float a = prev_u, b = u;
                    for (int it = 0; it < 64 && nextafterf(a, 1.0f) < b; it++) {
                        float m = 0.5f * (a + b);
                        if (m <= a || m >= b) break;
                        if (chosen_cell_key(env, axis ? fixed : m, axis ? m : fixed) == prev_key)
                            a = m;
                        else
                            b = m;
                    }
                    const float side[2] = {a, b};
                    for (int q = 0; q < 2; q++) {
                        float u1 = axis ? fixed : side[q], u2 = axis ? side[q] : fixed;
                        pn_light_sample s;
                        if (!pn_light_sample_point(L, l, p, u1, u2, &s)) continue;
                        tested++;
                        if (!env_sample_consistent(ec, &s)) inconsistent++;
                        float du, dvv, dpdf;
                        if (pn_distribution2d_sample(env->dist, u1, u2, &du, &dvv, &dpdf) &&
                            pn_distribution2d_pdf(env->dist, du, dvv) != dpdf)
                            dist_mismatch++;
                    }
                }
                prev_u = u;
                prev_key = key;
            }
        }
    CHECK(tested > 500);
    /* Two bugs this test found, now fixed: pn_distribution2d_sample could round (u, v) onto the
     * next cell's edge while returning the chosen cell's pdf; and the environment sample took its
     * radiance from the texel its direction maps back to but its pdf from the sampled texel.
     * Both must hold at every edge of the sampling CDF. */
    CHECK_MSG(inconsistent == 0, "%s: %ld of %ld samples at texel edges carry one texel's radiance and another's pdf",
              ec->label, inconsistent, tested);
    CHECK_MSG(dist_mismatch == 0, "%s: %ld of %ld pn_distribution2d samples outside their cell", ec->label,
              dist_mismatch, tested);
}

static pn_scene load_env_scene(pn_context ctx, const char *scene_name, const char *light_line) {
    char text[1024];
    snprintf(text, sizeof text,
             "LookAt 0 0 0  0 0 -1  0 1 0\n"
             "Camera \"perspective\" \"float fov\" [ 45 ]\n"
             "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n"
             "WorldBegin\n"
             "AttributeBegin\n"
             "  Rotate -90 1 0 0\n"
             "  %s\n"
             "AttributeEnd\n"
             "Shape \"sphere\" \"float radius\" [ 0.5 ]\n",
             light_line);
    if (!write_text(scene_name, text)) return NULL;
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, scene_name);
    pn_scene scene = NULL;
    if (pn_scene_load(ctx, path, &scene) != PN_OK) {
        fprintf(stderr, "  %s: %s\n", scene_name, pn_context_error_message(ctx));
        return NULL;
    }
    return scene;
}

static const pn_light *find_env_light(pn_scene scene) {
    const pn_lights *L = scene->lights;
    for (int i = 0; L && i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_ENVIRONMENT) return &L->lights[i];
    return NULL;
}

/* Direction cells for the light-space test: NC bands of equal cos theta, NP of phi. */
#define NC 12
#define NP 24

static void run_env_case(env_case *ec) {
    char file[64], scene_name[64], line[256];
    snprintf(file, sizeof file, "env_%dx%d.pfm", ec->w, ec->h);
    snprintf(scene_name, sizeof scene_name, "env_%dx%d.pbrt", ec->w, ec->h);
    snprintf(line, sizeof line, "LightSource \"infinite\" \"string filename\" \"%s\" \"float scale\" [ %g ]", file,
             (double)ec->scale);
    if (!write_pfm(file, ec->rgb, ec->w, ec->h)) {
        CHECK_MSG(0, "cannot write %s", file);
        return;
    }
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load_env_scene(ctx, scene_name, line);
    CHECK_MSG(scene != NULL, "%s: scene did not load", ec->label);
    const pn_light *l = scene ? find_env_light(scene) : NULL;
    CHECK_MSG(l != NULL, "%s: no environment light", ec->label);
    if (!l) goto done;
    const pn_lights *L = scene->lights;
    const pn_env *env = &L->envs[l->env];
    CHECK(env->equal_area == ec->equal_area && env->width == ec->w && env->height == ec->h);
    /* The image as loaded is ours (row 0 at the top), and the transform is the one we wrote. */
    CHECK(env->rgb && memcmp(env->rgb, ec->rgb, sizeof(float) * 3 * (size_t)(ec->w * ec->h)) == 0);
    vec3 up = mat4_apply_vector(&env->world_from_light, v3(0, 0, 1));
    CHECK(fabsf(up.x) < 1e-6f && fabsf(up.y - 1.0f) < 1e-6f && fabsf(up.z) < 1e-6f);
    if (!env->rgb || !env->dist) goto done;

    int ntex = ec->w * ec->h;
    double *tex_obs = calloc((size_t)ntex, sizeof(double));
    double dir_obs[NC * NP], dir_prob[NC * NP];
    memset(dir_obs, 0, sizeof dir_obs);
    run_stats st;
    memset(&st, 0, sizeof st);
    long radiance_mismatch = 0, black_hits = 0;
    pn_rng rng;
    seed_run(&rng, ec->label);
    vec3 p = v3(0.1f, 0.2f, -0.3f);
    for (long k = 0; k < N_SAMPLES; k++) {
        float u1, u2;
        draw(&rng, &u1, &u2);
        pn_light_sample s;
        st.drawn++;
        if (!pn_light_sample_point(L, l, p, u1, u2, &s)) continue;
        st.valid++;
        basic_checks(&st, &s, false);
        dv wl = world_to_light(dvf(s.wi));
        int t = env_texel_of(ec, wl);
        tex_obs[t] += 1.0;
        const float *px = ec->rgb + 3 * t;
        if (px[0] == 0.0f && px[1] == 0.0f && px[2] == 0.0f) black_hits++;
        vec3 want = v3_scale(v3(px[0], px[1], px[2]), ec->scale);
        /* A direction within rounding of a texel edge may be looked up in the neighbour; such
         * samples are counted, not checked. */
        if (s.radiance.x != want.x || s.radiance.y != want.y || s.radiance.z != want.z) {
            radiance_mismatch++;
        } else {
            double sin_theta = sqrt(wl.x * wl.x + wl.y * wl.y);
            double tol = ec->equal_area ? 1e-4 : 1e-3 + 1e-6 / sin_theta;
            check_pdf(&st, (double)s.pdf, env_density(ec, wl), tol);
        }
        double ct = fmax(-1.0, fmin(1.0, wl.z));
        double phi = atan2(wl.y, wl.x);
        if (phi < 0.0) phi += 2.0 * PI_D;
        int ic = (int)fmin((1.0 - ct) * 0.5 * NC, NC - 1), ip = (int)fmin(phi / (2.0 * PI_D) * NP, NP - 1);
        dir_obs[ic * NP + ip] += 1.0;
    }
    report_stats(ec->label, &st, N_SAMPLES);
    CHECK_MSG(black_hits == 0, "%s: %ld samples in black texels", ec->label, black_hits);
    CHECK_MSG(radiance_mismatch <= N_SAMPLES / 2000, "%s: %ld samples whose radiance is not their texel's", ec->label,
              radiance_mismatch);

    /* Texel frequencies against weight x solid angle. */
    char label[96];
    snprintf(label, sizeof label, "%s: texels", ec->label);
    CHECK_MSG(chi2_accepts(label, tex_obs, ec->prob, ntex, (double)N_SAMPLES, true), "%s", label);

    /* Direction cells of equal solid angle: the claimed density integrated over each cell.
     * Lat-long: the density times sin theta is constant within a texel, so a cell's mass is
     * the texels' masses times their overlap in (phi, theta). Equal-area: midpoint quadrature
     * over the cell in (cos theta, phi), where the density is constant per texel. */
    for (int ic = 0; ic < NC; ic++)
        for (int ip = 0; ip < NP; ip++) {
            double c0 = 1.0 - 2.0 * ic / NC, c1 = 1.0 - 2.0 * (ic + 1) / NC;
            double ph0 = 2.0 * PI_D * ip / NP, ph1 = 2.0 * PI_D * (ip + 1) / NP;
            double mass = 0.0;
            if (!ec->equal_area) {
                double v0 = acos(c0) / PI_D, v1 = acos(c1) / PI_D, u0 = ph0 / (2.0 * PI_D), u1 = ph1 / (2.0 * PI_D);
                for (int y = 0; y < ec->h; y++) {
                    double ov = fmin(v1, (y + 1.0) / ec->h) - fmax(v0, (double)y / ec->h);
                    if (ov <= 0.0) continue;
                    for (int x = 0; x < ec->w; x++) {
                        double ou = fmin(u1, (x + 1.0) / ec->w) - fmax(u0, (double)x / ec->w);
                        if (ou > 0.0) mass += ec->prob[y * ec->w + x] * ou * ov * ec->w * ec->h;
                    }
                }
            } else {
                const int S = 128; /* 40 leaves ~1e-3 errors that 2M-sample runs detect */
                for (int j = 0; j < S; j++)
                    for (int i = 0; i < S; i++) {
                        double ct = c0 + (c1 - c0) * (j + 0.5) / S, ph = ph0 + (ph1 - ph0) * (i + 0.5) / S;
                        double sn = sqrt(fmax(0.0, 1.0 - ct * ct));
                        mass += env_density(ec, dv3(sn * cos(ph), sn * sin(ph), ct));
                    }
                mass *= 4.0 * PI_D / (NC * NP) / (S * S);
            }
            dir_prob[ic * NP + ip] = mass;
        }
    /* Quadrature leaves the masses a hair off summing to 1; rescale. */
    double total = 0.0;
    for (int i = 0; i < NC * NP; i++) total += dir_prob[i];
    CHECK_MSG(fabs(total - 1.0) < 2e-3, "%s: direction cells hold %.6f of the mass", ec->label, total);
    for (int i = 0; i < NC * NP; i++) dir_prob[i] /= total;
    snprintf(label, sizeof label, "%s: directions", ec->label);
    CHECK_MSG(chi2_accepts(label, dir_obs, dir_prob, NC * NP, (double)N_SAMPLES, true), "%s", label);
    free(tex_obs);

    /* Unbiased irradiance: radiance cos / pdf with 2^16 Sobol' points against quadrature. */
    const dv normals[3] = {dv3(0, 0, 1), dv3(0, 1, 0), dv_norm(dv3(1.0, -0.5, 0.3))};
    double worst = 0.0;
    for (int ni = 0; ni < 3; ni++) {
        dv ref = env_quadrature_irradiance(ec, normals[ni]);
        dv est = dv3(0, 0, 0);
        const uint32_t M = 1u << 16;
        for (uint32_t i = 0; i < M; i++) {
            pn_light_sample s;
            if (!pn_light_sample_point(L, l, p, pn_sobol_sample(i, 0, 11u), pn_sobol_sample(i, 1, 11u), &s)) continue;
            double c = dv_dot(dvf(s.wi), normals[ni]);
            if (c <= 0.0) continue;
            est = dv_add(est, dv_scale(dvf(s.radiance), c / (double)s.pdf));
        }
        est = dv_scale(est, 1.0 / M);
        worst =
            fmax(worst, fmax(fabs(est.x / ref.x - 1.0), fmax(fabs(est.y / ref.y - 1.0), fabs(est.z / ref.z - 1.0))));
        CHECK_MSG(fabs(est.x - ref.x) <= 0.01 * ref.x && fabs(est.y - ref.y) <= 0.01 * ref.y &&
                      fabs(est.z - ref.z) <= 0.01 * ref.z,
                  "%s, normal %d: estimate (%.5g %.5g %.5g), quadrature (%.5g %.5g %.5g)", ec->label, ni, est.x, est.y,
                  est.z, ref.x, ref.y, ref.z);
        /* The light-PDF weight (unoccluded irradiance from 9 spherical harmonics) follows the
         * quadrature's luminance: order-2 harmonics smooth a bright texel (these maps have contrasts of
         * 300-800), hence 30%. */
        double ref_lum = 0.2126 * ref.x + 0.7152 * ref.y + 0.0722 * ref.z;
        double sh = (double)pn_light_irradiance_estimate(L, l, p, fv(normals[ni]));
        double flat = PI_D * (double)env->average_luminance;
        fprintf(stderr, "  %-34s normal %d: harmonics irradiance %.5g, quadrature %.5g, pi x mean %.5g\n", ec->label,
                ni, sh, ref_lum, flat);
        CHECK_MSG(fabs(sh - ref_lum) <= 0.3 * ref_lum, "%s, normal %d: harmonics irradiance %.5g vs %.5g", ec->label,
                  ni, sh, ref_lum);
        /* And pn_env_radiance agrees with our texel lookup along the normal. */
        dv wl = world_to_light(normals[ni]);
        const float *px = ec->rgb + 3 * env_texel_of(ec, wl);
        vec3 le = pn_lights_environment_radiance(L, fv(normals[ni]));
        CHECK_NEAR(le.y, (double)px[1] * (double)ec->scale, 1e-6 * (1.0 + (double)px[1]));
    }

    fprintf(stderr, "  %-34s irradiance: largest relative error %.2g (allowed 0.01)\n", ec->label, worst);
    env_edge_consistency(ec, L, l, env);

done:
    pn_scene_free(scene);
    pn_context_free(ctx);
    remove_file(file);
    remove_file(scene_name);
}

/* A dim, slowly varying background with a few bright texels (one near a pole, one pure red /
 * blue) and a black block that must never be sampled. */
static void fill_env(float *rgb, int w, int h, const int (*bright)[2], const float (*colour)[3], int nb, int bx0,
                     int bx1, int by0, int by1) {
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *px = rgb + 3 * (y * w + x);
            px[0] = 0.02f + 0.01f * (float)x / (float)w;
            px[1] = 0.03f;
            px[2] = 0.05f + 0.02f * (float)y / (float)h;
            if (x >= bx0 && x <= bx1 && y >= by0 && y <= by1) px[0] = px[1] = px[2] = 0.0f;
        }
    for (int i = 0; i < nb; i++) memcpy(rgb + 3 * (bright[i][1] * w + bright[i][0]), colour[i], sizeof colour[i]);
}

static void test_env_equal_area(void) {
    enum { W = 16, H = 16 };
    static float rgb[W * H * 3];
    static double prob[W * H];
    const int bright[4][2] = {{3, 4}, {12, 10}, {8, 8}, {0, 15}};
    const float colour[4][3] = {{40, 30, 20}, {5, 8, 60}, {15, 15, 15}, {10, 0, 0}};
    fill_env(rgb, W, H, bright, colour, 4, 5, 7, 12, 14);
    env_case ec = {"equal-area 16x16", W, H, true, rgb, 1.5f, prob};
    env_compute_prob(&ec);
    run_env_case(&ec);
}

static void test_env_latlong(void) {
    enum { W = 32, H = 16 };
    static float rgb[W * H * 3];
    static double prob[W * H];
    const int bright[4][2] = {{5, 0}, {20, 8}, {31, 11}, {14, 15}};
    const float colour[4][3] = {{50, 50, 50}, {10, 20, 5}, {2, 2, 30}, {0, 0, 40}};
    fill_env(rgb, W, H, bright, colour, 4, 0, 9, 14, 15);
    env_case ec = {"lat-long 32x16", W, H, false, rgb, 0.75f, prob};
    env_compute_prob(&ec);
    run_env_case(&ec);
}

/* The equal-area map's area element is 4 pi everywhere (away from its folds), which the
 * texel masses above assume. */
static void test_equal_area_jacobian(void) {
    int bad = 0, tested = 0;
    double worst = 0.0;
    const double h = 1e-3;
    for (int j = 0; j < 40; j++)
        for (int i = 0; i < 40; i++) {
            double u = (i + 0.5) / 40.0, v = (j + 0.5) / 40.0;
            double x = 2.0 * u - 1.0, y = 2.0 * v - 1.0;
            /* Skip points near the creases: the axes and the diamond |x| + |y| = 1. */
            if (fabs(x) < 4.0 * h || fabs(y) < 4.0 * h || fabs(fabs(x) + fabs(y) - 1.0) < 8.0 * h) continue;
            dv du = dv_scale(dv_sub(dvf(pn_equal_area_square_to_sphere((float)(u + h), (float)v)),
                                    dvf(pn_equal_area_square_to_sphere((float)(u - h), (float)v))),
                             0.5 / h);
            dv dvv = dv_scale(dv_sub(dvf(pn_equal_area_square_to_sphere((float)u, (float)(v + h))),
                                     dvf(pn_equal_area_square_to_sphere((float)u, (float)(v - h)))),
                              0.5 / h);
            double jac = dv_len(dv_cross(du, dvv));
            double rel = fabs(jac / (4.0 * PI_D) - 1.0);
            if (rel > worst) worst = rel;
            if (rel > 5e-3) bad++;
            tested++;
        }
    CHECK(tested > 1000);
    CHECK_MSG(bad == 0, "%d points where the area element is not 4 pi (worst rel. error %.3g)", bad, worst);
}

/* A constant environment: directions uniform over the sphere, pdf 1 / (4 pi). */
static void test_env_constant(void) {
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load_env_scene(ctx, "env_const.pbrt", "LightSource \"infinite\" \"rgb L\" [ 0.5 0.6 0.7 ]");
    const pn_light *l = scene ? find_env_light(scene) : NULL;
    CHECK(l != NULL);
    if (l) {
        double obs[NC * NP], prob[NC * NP];
        memset(obs, 0, sizeof obs);
        for (int i = 0; i < NC * NP; i++) prob[i] = 1.0 / (NC * NP);
        run_stats st;
        memset(&st, 0, sizeof st);
        long bad_radiance = 0;
        pn_rng rng;
        seed_run(&rng, "constant environment");
        for (long k = 0; k < N_SAMPLES; k++) {
            float u1, u2;
            draw(&rng, &u1, &u2);
            pn_light_sample s;
            st.drawn++;
            if (!pn_light_sample_point(scene->lights, l, v3(0, 0, 0), u1, u2, &s)) continue;
            st.valid++;
            basic_checks(&st, &s, false);
            check_pdf(&st, (double)s.pdf, 1.0 / (4.0 * PI_D), 1e-6);
            if (fabsf(s.radiance.x - 0.5f) > 1e-6f || fabsf(s.radiance.z - 0.7f) > 1e-6f) bad_radiance++;
            dv w = dvf(s.wi);
            double phi = atan2(w.y, w.x);
            if (phi < 0.0) phi += 2.0 * PI_D;
            int ic = (int)fmin((1.0 - fmax(-1.0, fmin(1.0, w.z))) * 0.5 * NC, NC - 1);
            obs[ic * NP + (int)fmin(phi / (2.0 * PI_D) * NP, NP - 1)] += 1.0;
        }
        report_stats("constant environment", &st, N_SAMPLES);
        CHECK(bad_radiance == 0);
        CHECK(chi2_accepts("constant environment", obs, prob, NC * NP, (double)N_SAMPLES, true));
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
    remove_file("env_const.pbrt");
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_light_sampling_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        fprintf(stderr, "mkdtemp failed\n");
        exit(1);
    }
}

static void test_teardown(void) {
    rmdir(tmpdir);
}

/* Goniometric light: I times the nearest texel of its square equal-area image, looked up in the
 * light's frame with y and z swapped (pbrt-v4). The scene places it under Rotate -90 about x, so
 * light-from-world is Rotate +90 about x: (x, y, z) -> (x, -z, y); the swap then gives
 * (x, y, -z). The expected texel is computed from that, independently of the light code. */
static void test_goniometric(void) {
    enum { G = 16 };
    float rgb[3 * G * G];
    for (int i = 0; i < G * G; i++) {
        float v = 1.0f + (float)i; /* a distinct value per texel, as the channel mean */
        rgb[3 * i] = v * 0.5f;
        rgb[3 * i + 1] = v;
        rgb[3 * i + 2] = v * 1.5f;
    }
    CHECK(write_pfm("gonio.pfm", rgb, G, G));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load_env_scene(
        ctx, "gonio.pbrt", "LightSource \"goniometric\" \"rgb I\" [ 2 2 2 ] \"string filename\" \"gonio.pfm\"");
    CHECK(scene != NULL);
    const pn_lights *L = scene ? scene->lights : NULL;
    const pn_light *l = NULL;
    for (int i = 0; L && i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_GONIOMETRIC) l = &L->lights[i];
    CHECK(l != NULL);
    if (l) {
        pn_rng rng;
        pn_rng_seed(&rng, 77, 1);
        int checked = 0, wrong = 0;
        for (int k = 0; k < 2000; k++) {
            vec3 w = pn_sample_uniform_sphere(pn_rng_float(&rng), pn_rng_float(&rng)); /* light -> receiver */
            float dist = 0.5f + 3.0f * pn_rng_float(&rng);
            vec3 p = v3_add(l->p, v3_scale(w, dist));
            float u, v;
            pn_equal_area_sphere_to_square(v3(w.x, w.y, -w.z), &u, &v);
            int tx = (int)(u * G), ty = (int)(v * G);
            if (tx < 0 || ty < 0 || tx >= G || ty >= G) continue;
            /* Skip directions within float rounding of a texel edge. */
            if (fabsf(u * G - roundf(u * G)) < 1e-3f || fabsf(v * G - roundf(v * G)) < 1e-3f) continue;
            double texel = 1.0 + (double)(ty * G + tx);
            pn_light_sample s;
            if (!pn_light_sample_point(L, l, p, 0.5f, 0.5f, &s)) {
                wrong++;
                continue;
            }
            double expected = 2.0 * texel / ((double)dist * (double)dist);
            if (fabs((double)s.radiance.y - expected) > 1e-4 * expected) wrong++;
            checked++;
            /* The PDF weight is the same intensity times cos / d^2 (normal facing the light). */
            double e = (double)pn_light_irradiance_estimate(L, l, p, v3_neg(w));
            if (fabs(e - expected) > 1e-4 * expected) wrong++;
        }
        CHECK(checked > 1500);
        CHECK_MSG(wrong == 0, "%d of %d goniometric samples off the expected texel", wrong, checked);
    }
    pn_scene_free(scene);
    /* pbrt-v4's goniometric image must be square. */
    float flat[3 * 4 * 2] = {0};
    CHECK(write_pfm("gonio42.pfm", flat, 4, 2));
    pn_scene bad =
        load_env_scene(ctx, "gonio42.pbrt", "LightSource \"goniometric\" \"string filename\" \"gonio42.pfm\"");
    CHECK(bad == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "must be square");
    pn_scene_free(bad);
    pn_context_free(ctx);
    remove_file("gonio.pfm");
    remove_file("gonio.pbrt");
    remove_file("gonio42.pfm");
    remove_file("gonio42.pbrt");
}

PN_TESTS(TEST(test_setup), TEST(test_chi2_machinery), TEST(test_triangle_light), TEST(test_rectangle_light),
         TEST(test_disk_light), TEST(test_disk_reference_solid_angle), TEST(test_sphere_light), TEST(test_spot_falloff),
         TEST(test_point_and_distant), TEST(test_equal_area_jacobian), TEST(test_env_equal_area),
         TEST(test_env_latlong), TEST(test_env_constant), TEST(test_goniometric), TEST(test_teardown))
