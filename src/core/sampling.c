/* sampling.c — sample warps, spherical rectangle and sphere-cone sampling, and tabulated 1-D /
 * 2-D distributions (see sampling.h).
 *
 * Geometry that is prone to cancellation (spherical excess of a rectangle, cones of distant
 * spheres, CDFs) is evaluated in double precision; results are converted to float at the end.
 */
#include "core/sampling.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#define PN_ONE_MINUS_EPS 0x1.fffffep-1f
#define PN_PI_D 3.14159265358979323846

/* ---- small double-precision vector helpers ------------------------------------------------ */

typedef struct dvec3 {
    double x, y, z;
} dvec3;

static inline dvec3 d3(double x, double y, double z) {
    return (dvec3){x, y, z};
}
static inline dvec3 d3_from(vec3 a) {
    return d3((double)a.x, (double)a.y, (double)a.z);
}
static inline dvec3 d3_sub(dvec3 a, dvec3 b) {
    return d3(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline dvec3 d3_scale(dvec3 a, double s) {
    return d3(a.x * s, a.y * s, a.z * s);
}
static inline double d3_dot(dvec3 a, dvec3 b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline dvec3 d3_cross(dvec3 a, dvec3 b) {
    return d3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double d3_length(dvec3 a) {
    return sqrt(d3_dot(a, a));
}

static inline double clampd(double x, double lo, double hi) {
    return x < lo ? lo : (x > hi ? hi : x);
}

/* Uniform numbers from callers are expected in [0, 1); be forgiving about 1.0 and NaN. */
static inline float clamp_unit(float u) {
    if (!(u >= 0.0f)) return 0.0f;
    return u < PN_ONE_MINUS_EPS ? u : PN_ONE_MINUS_EPS;
}

/* ---- simple warps ------------------------------------------------------------------------ */

void pn_sample_uniform_triangle(float u1, float u2, float *b0, float *b1) {
    /* Heitz 2019: split the square along its diagonal and shear each half onto the triangle;
     * both pieces are affine with the same Jacobian, so the map is area preserving. */
    float a, b;
    if (u2 > u1) {
        a = 0.5f * u1;
        b = u2 - a;
    } else {
        b = 0.5f * u2;
        a = u1 - b;
    }
    *b0 = a;
    *b1 = b;
}

void pn_sample_concentric_disk(float u1, float u2, float *x, float *y) {
    float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) {
        *x = 0.0f;
        *y = 0.0f;
        return;
    }
    float r, phi;
    if (fabsf(a) > fabsf(b)) {
        r = a;
        phi = (PN_PI / 4.0f) * (b / a);
    } else {
        r = b;
        phi = PN_PI / 2.0f - (PN_PI / 4.0f) * (a / b);
    }
    *x = r * cosf(phi);
    *y = r * sinf(phi);
}

vec3 pn_sample_uniform_sphere(float u1, float u2) {
    float z = 1.0f - 2.0f * u1;
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    float phi = 2.0f * PN_PI * u2;
    return v3(r * cosf(phi), r * sinf(phi), z);
}

vec3 pn_sample_cosine_hemisphere(float u1, float u2) {
    float x, y;
    pn_sample_concentric_disk(u1, u2, &x, &y);
    float z = sqrtf(fmaxf(0.0f, 1.0f - x * x - y * y));
    return v3(x, y, z);
}

/* ---- spherical rectangles ---------------------------------------------------------------- */

bool pn_spherical_rectangle_init(pn_spherical_rectangle *sr, vec3 p, vec3 corner, vec3 e1, vec3 e2) {
    sr->solid_angle = 0.0f;
    sr->s = 0.0;
    dvec3 ex = d3_from(e1), ey = d3_from(e2);
    double len1 = d3_length(ex), len2 = d3_length(ey);
    if (!(len1 > 0.0) || !(len2 > 0.0) || !isfinite(len1) || !isfinite(len2)) return false;
    /* Local frame: x along e1, y along e2, z facing away from the rectangle's side of p. */
    dvec3 xa = d3_scale(ex, 1.0 / len1), ya = d3_scale(ey, 1.0 / len2);
    dvec3 za = d3_cross(xa, ya);
    double zl = d3_length(za);
    if (!(zl > 0.0)) return false;
    za = d3_scale(za, 1.0 / zl);
    dvec3 d = d3_sub(d3_from(corner), d3_from(p));
    double z0 = d3_dot(d, za);
    if (z0 > 0.0) z0 = -z0;
    /* p in (or numerically indistinguishable from) the rectangle's plane. */
    double scale = fmax(fmax(d3_length(d), len1), len2);
    if (!(-z0 > 1e-9 * scale)) return false;
    double x0 = d3_dot(d, xa), y0 = d3_dot(d, ya);
    double x1 = x0 + len1, y1 = y0 + len2;

    /* Normals of the four planes through p and each rectangle edge (already simplified for
     * the axis-aligned local frame), then the interior angles of the spherical quad. */
    double z0sq = z0 * z0;
    dvec3 n0 = d3_scale(d3(0.0, z0, -y0), 1.0 / sqrt(z0sq + y0 * y0));
    dvec3 n1 = d3_scale(d3(-z0, 0.0, x1), 1.0 / sqrt(z0sq + x1 * x1));
    dvec3 n2 = d3_scale(d3(0.0, -z0, y1), 1.0 / sqrt(z0sq + y1 * y1));
    dvec3 n3 = d3_scale(d3(z0, 0.0, -x0), 1.0 / sqrt(z0sq + x0 * x0));
    double g0 = acos(clampd(-d3_dot(n0, n1), -1.0, 1.0));
    double g1 = acos(clampd(-d3_dot(n1, n2), -1.0, 1.0));
    double g2 = acos(clampd(-d3_dot(n2, n3), -1.0, 1.0));
    double g3 = acos(clampd(-d3_dot(n3, n0), -1.0, 1.0));
    double k = 2.0 * PN_PI_D - g2 - g3;
    double s = g0 + g1 - k;
    if (!(s > 0.0) || !isfinite(s)) return false;

    sr->corner = corner;
    sr->e1 = e1;
    sr->e2 = e2;
    sr->len1 = len1;
    sr->len2 = len2;
    sr->x0 = x0;
    sr->y0 = y0;
    sr->x1 = x1;
    sr->y1 = y1;
    sr->z0 = z0;
    sr->z0sq = z0sq;
    sr->b0 = n0.z;
    sr->b1 = n2.z;
    sr->b0sq = n0.z * n0.z;
    sr->k = k;
    sr->s = s;
    sr->solid_angle = (float)s;
    return sr->solid_angle > 0.0f;
}

vec3 pn_spherical_rectangle_sample_ab(const pn_spherical_rectangle *sr, float u1, float u2, float *a_out,
                                      float *b_out) {
    double u = (double)clamp_unit(u1), v = (double)clamp_unit(u2);
    /* Invert the area of the sub-quad left of x = xu: a spherical-triangle relation gives the
     * cosine of the angle of the boundary plane, from which xu follows. */
    double au = u * sr->s + sr->k;
    double fu = (cos(au) * sr->b0 - sr->b1) / sin(au);
    double cu = (fu > 0.0 ? 1.0 : -1.0) / sqrt(fu * fu + sr->b0sq);
    cu = clampd(cu, -1.0, 1.0);
    double xu = -(cu * sr->z0) / sqrt(fmax(1.0 - cu * cu, 1e-300));
    if (!isfinite(xu)) xu = 0.0;
    xu = clampd(xu, sr->x0, sr->x1);
    /* Along the chosen line the solid angle is uniform in the sine of the elevation h. */
    double dd = sqrt(xu * xu + sr->z0sq);
    double h0 = sr->y0 / sqrt(dd * dd + sr->y0 * sr->y0);
    double h1 = sr->y1 / sqrt(dd * dd + sr->y1 * sr->y1);
    double hv = h0 + v * (h1 - h0);
    double hv2 = hv * hv;
    double yv = hv2 < 1.0 - 1e-14 ? (hv * dd) / sqrt(1.0 - hv2) : sr->y1;
    if (!isfinite(yv)) yv = sr->y1;
    yv = clampd(yv, sr->y0, sr->y1);
    /* Rebuild the point from the rectangle's own parametrisation so it lies on it exactly. */
    double a = clampd((xu - sr->x0) / sr->len1, 0.0, 1.0);
    double b = clampd((yv - sr->y0) / sr->len2, 0.0, 1.0);
    if (a_out) *a_out = (float)a;
    if (b_out) *b_out = (float)b;
    return v3((float)((double)sr->corner.x + a * (double)sr->e1.x + b * (double)sr->e2.x),
              (float)((double)sr->corner.y + a * (double)sr->e1.y + b * (double)sr->e2.y),
              (float)((double)sr->corner.z + a * (double)sr->e1.z + b * (double)sr->e2.z));
}

vec3 pn_spherical_rectangle_sample(const pn_spherical_rectangle *sr, float u1, float u2) {
    return pn_spherical_rectangle_sample_ab(sr, u1, u2, NULL, NULL);
}

/* Solid angle of the triangle (a, b, c) seen from the origin (Van Oosterom and Strackee 1983):
 * tan(omega / 2) = |a . (b x c)| / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|). */
static double triangle_solid_angle(dvec3 a, dvec3 b, dvec3 c) {
    double la = d3_length(a), lb = d3_length(b), lc = d3_length(c);
    double num = fabs(d3_dot(a, d3_cross(b, c)));
    double den = la * lb * lc + d3_dot(a, b) * lc + d3_dot(a, c) * lb + d3_dot(b, c) * la;
    return 2.0 * atan2(num, den);
}

double pn_rectangle_solid_angle(vec3 p, vec3 corner, vec3 e1, vec3 e2) {
    dvec3 o = d3_from(p);
    dvec3 c0 = d3_sub(d3_from(corner), o);
    dvec3 ex = d3_from(e1), ey = d3_from(e2);
    dvec3 c1 = d3(c0.x + ex.x, c0.y + ex.y, c0.z + ex.z);
    dvec3 c3 = d3(c0.x + ey.x, c0.y + ey.y, c0.z + ey.z);
    dvec3 c2 = d3(c1.x + ey.x, c1.y + ey.y, c1.z + ey.z);
    double s = triangle_solid_angle(c0, c1, c2) + triangle_solid_angle(c0, c2, c3);
    return isfinite(s) && s > 0.0 ? s : 0.0;
}

/* ---- spheres ----------------------------------------------------------------------------- */

/* 1 - cos(theta_max) of the cone around a sphere, computed without cancellation; returns a
 * value <= 0 when p is not strictly outside. */
static double cone_one_minus_cos(dvec3 dc, double radius, double *dist_out) {
    double dist2 = d3_dot(dc, dc);
    double r2 = radius * radius;
    *dist_out = sqrt(dist2);
    if (!(dist2 > r2)) return 0.0;
    double sin2 = r2 / dist2;
    double cosmax = sqrt(fmax(0.0, 1.0 - sin2));
    return sin2 / (1.0 + cosmax);
}

float pn_sphere_cone_pdf(vec3 center, float radius, vec3 p) {
    double dist;
    double omc = cone_one_minus_cos(d3_sub(d3_from(center), d3_from(p)), (double)radius, &dist);
    if (!(omc > 0.0)) return 0.0f;
    float pdf = (float)(1.0 / (2.0 * PN_PI_D * omc));
    return isfinite(pdf) ? pdf : 0.0f;
}

bool pn_sample_sphere_from_point(vec3 center, float radius, vec3 p, float u1, float u2, vec3 *y, float *pdf) {
    if (!(radius > 0.0f)) return false;
    dvec3 c = d3_from(center), o = d3_from(p);
    dvec3 dc = d3_sub(c, o);
    double dist;
    double r = (double)radius;
    double omc = cone_one_minus_cos(dc, r, &dist);
    if (!(omc > 0.0) || !isfinite(omc)) return false;
    double pdf_d = 1.0 / (2.0 * PN_PI_D * omc);
    if (!((float)pdf_d < FLT_MAX)) return false;

    /* Uniform in the cap: 1 - cos(theta) uniform in [0, omc]. */
    double t = (double)clamp_unit(u1) * omc;
    double cos_t = 1.0 - t;
    double sin_t = sqrt(fmax(0.0, t * (2.0 - t)));
    double phi = 2.0 * PN_PI_D * (double)clamp_unit(u2);

    /* Orthonormal frame around the axis (Duff et al. 2017, in double). */
    dvec3 w = d3_scale(dc, 1.0 / dist);
    double sign = copysign(1.0, w.z);
    double a = -1.0 / (sign + w.z);
    double bb = w.x * w.y * a;
    dvec3 tx = d3(1.0 + sign * w.x * w.x * a, sign * bb, -sign * w.x);
    dvec3 ty = d3(bb, sign + w.y * w.y * a, -w.y);
    double cp = cos(phi) * sin_t, sp = sin(phi) * sin_t;
    dvec3 dir = d3(tx.x * cp + ty.x * sp + w.x * cos_t, tx.y * cp + ty.y * sp + w.y * cos_t,
                   tx.z * cp + ty.z * sp + w.z * cos_t);

    /* Nearest intersection of the ray o + s dir with the sphere. The direction is inside the
     * cone, so the discriminant is non-negative up to rounding. */
    double disc = r * r - dist * dist * sin_t * sin_t;
    double s = dist * cos_t - sqrt(fmax(0.0, disc));
    dvec3 hit = d3(o.x + s * dir.x, o.y + s * dir.y, o.z + s * dir.z);
    /* Project onto the sphere to remove the remaining rounding error. */
    dvec3 rel = d3_sub(hit, c);
    double rl = d3_length(rel);
    if (rl > 0.0) rel = d3_scale(rel, r / rl);
    *y = v3((float)(c.x + rel.x), (float)(c.y + rel.y), (float)(c.z + rel.z));
    *pdf = (float)pdf_d;
    return true;
}

/* ---- 1-D discrete distribution ----------------------------------------------------------- */

struct pn_distribution1d {
    int n;
    double total;
    double cdf[]; /* n + 1 entries, cdf[0] = 0, cdf[n] = 1, constant across zero weights */
};

static inline double clean_weight(float w) {
    return (isfinite(w) && w > 0.0f) ? (double)w : 0.0;
}

pn_distribution1d *pn_distribution1d_create(const float *weights, int n) {
    if (n <= 0 || !weights) return NULL;
    if ((size_t)n > (SIZE_MAX - sizeof(pn_distribution1d)) / sizeof(double) - 1) return NULL;
    pn_distribution1d *d = malloc(sizeof *d + ((size_t)n + 1) * sizeof(double));
    if (!d) return NULL;
    d->n = n;
    double run = 0.0;
    d->cdf[0] = 0.0;
    for (int i = 0; i < n; i++) {
        run += clean_weight(weights[i]);
        d->cdf[i + 1] = run;
    }
    if (!(run > 0.0) || !isfinite(run)) {
        free(d);
        return NULL;
    }
    d->total = run;
    /* After the last positive weight the running sum equals run, so the division yields
     * exactly 1 and zero-weight tails can never be selected. */
    for (int i = 1; i <= n; i++) d->cdf[i] /= run;
    d->cdf[n] = 1.0;
    return d;
}

/* Largest i in [0, n-1] with cdf[i] <= u (cdf[0] = 0 <= u always). */
static int find_interval_d(const double *cdf, int n, double u) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = lo + (hi - lo + 1) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

static int find_interval_f(const float *cdf, int n, float u) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = lo + (hi - lo + 1) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

int pn_distribution1d_sample_discrete(const pn_distribution1d *d, float u, float *pmf, float *u_remapped) {
    double uu = (double)clamp_unit(u);
    int i = find_interval_d(d->cdf, d->n, uu);
    double width = d->cdf[i + 1] - d->cdf[i];
    if (pmf) *pmf = (float)width;
    if (u_remapped) {
        float r = width > 0.0 ? (float)((uu - d->cdf[i]) / width) : 0.0f;
        *u_remapped = clamp_unit(r);
    }
    return i;
}

float pn_distribution1d_sample_continuous(const pn_distribution1d *d, float u, float *pdf, int *index) {
    float pmf, r;
    int i = pn_distribution1d_sample_discrete(d, u, &pmf, &r);
    if (index) *index = i;
    if (pdf) *pdf = pmf * (float)d->n;
    double x = ((double)i + (double)r) / (double)d->n;
    return clamp_unit((float)x);
}

float pn_distribution1d_pdf(const pn_distribution1d *d, int index) {
    if (!d || index < 0 || index >= d->n) return 0.0f;
    return (float)(d->cdf[index + 1] - d->cdf[index]);
}

int pn_distribution1d_count(const pn_distribution1d *d) {
    return d ? d->n : 0;
}

double pn_distribution1d_total(const pn_distribution1d *d) {
    return d ? d->total : 0.0;
}

void pn_distribution1d_free(pn_distribution1d *d) {
    free(d);
}

/* ---- 2-D piecewise-constant distribution ------------------------------------------------- */

/* The marginal CDF over rows is kept in double (it is short); each row's conditional CDF is
 * kept in float to halve the memory of large environment maps. Densities are derived from
 * CDF differences, so the reported pdf is exactly the density the sampler realises. */
struct pn_distribution2d {
    int w, h;
    double *marginal; /* h + 1 entries */
    float *cond;      /* h rows of w + 1 entries */
};

pn_distribution2d *pn_distribution2d_create(const float *weights, int w, int h) {
    if (!weights || w <= 0 || h <= 0) return NULL;
    size_t sw = (size_t)w, sh = (size_t)h;
    if (sw + 1 > SIZE_MAX / sizeof(float) / sh) return NULL;
    size_t cond_count = (sw + 1) * sh;
    size_t header = (sizeof(pn_distribution2d) + sizeof(double) - 1) / sizeof(double) * sizeof(double);
    size_t marg_bytes = (sh + 1) * sizeof(double);
    if (cond_count > (SIZE_MAX - header - marg_bytes) / sizeof(float)) return NULL;
    unsigned char *mem = malloc(header + marg_bytes + cond_count * sizeof(float));
    if (!mem) return NULL;
    pn_distribution2d *d = (pn_distribution2d *)mem;
    d->w = w;
    d->h = h;
    d->marginal = (double *)(mem + header);
    d->cond = (float *)(mem + header + marg_bytes);

    double total = 0.0;
    d->marginal[0] = 0.0;
    for (size_t r = 0; r < sh; r++) {
        const float *row = weights + r * sw;
        float *c = d->cond + r * (sw + 1);
        double run = 0.0;
        for (size_t i = 0; i < sw; i++) run += clean_weight(row[i]);
        if (run > 0.0 && isfinite(run)) {
            double acc = 0.0;
            c[0] = 0.0f;
            for (size_t i = 0; i < sw; i++) {
                acc += clean_weight(row[i]);
                c[i + 1] = (float)(acc / run);
            }
        } else {
            /* Never sampled (zero marginal width); keep a valid uniform CDF anyway. */
            run = 0.0;
            for (size_t i = 0; i <= sw; i++) c[i] = (float)((double)i / (double)sw);
        }
        c[sw] = 1.0f;
        total += run;
        d->marginal[r + 1] = total;
    }
    if (!(total > 0.0) || !isfinite(total)) {
        free(mem);
        return NULL;
    }
    for (size_t r = 1; r <= sh; r++) d->marginal[r] /= total;
    d->marginal[sh] = 1.0;
    return d;
}

bool pn_distribution2d_sample(const pn_distribution2d *d, float u1, float u2, float *u, float *v, float *pdf) {
    if (!d) return false;
    double uv = (double)clamp_unit(u2);
    int r = find_interval_d(d->marginal, d->h, uv);
    double pr = d->marginal[r + 1] - d->marginal[r];
    double rv = pr > 0.0 ? (uv - d->marginal[r]) / pr : 0.0;

    const float *c = d->cond + (size_t)r * ((size_t)d->w + 1);
    float uu = clamp_unit(u1);
    int col = find_interval_f(c, d->w, uu);
    double pc = (double)c[col + 1] - (double)c[col];
    double ru = pc > 0.0 ? ((double)uu - (double)c[col]) / pc : 0.0;

    /* Keep the continuous coordinates inside the chosen cell and below 1. */
    double fu = ((double)col + fmin(ru, 1.0 - 1e-9)) / (double)d->w;
    double fv = ((double)r + fmin(rv, 1.0 - 1e-9)) / (double)d->h;
    /* Rounding to float may carry a coordinate onto the next cell's edge; step back so that
     * the point lies in the cell whose probability is returned. */
    float fu_f = clamp_unit((float)fu), fv_f = clamp_unit((float)fv);
    while (fu_f > 0.0f && (int)((double)fu_f * (double)d->w) > col) fu_f = nextafterf(fu_f, 0.0f);
    while (fv_f > 0.0f && (int)((double)fv_f * (double)d->h) > r) fv_f = nextafterf(fv_f, 0.0f);
    *u = fu_f;
    *v = fv_f;
    float p = (float)(pr * pc * (double)d->w * (double)d->h);
    *pdf = p;
    return p > 0.0f && isfinite(p);
}

float pn_distribution2d_pdf(const pn_distribution2d *d, float u, float v) {
    if (!d || !(u == u) || !(v == v)) return 0.0f;
    int col = (int)clampd((double)u * (double)d->w, 0.0, (double)(d->w - 1));
    int r = (int)clampd((double)v * (double)d->h, 0.0, (double)(d->h - 1));
    const float *c = d->cond + (size_t)r * ((size_t)d->w + 1);
    double pr = d->marginal[r + 1] - d->marginal[r];
    double pc = (double)c[col + 1] - (double)c[col];
    return (float)(pr * pc * (double)d->w * (double)d->h);
}

void pn_distribution2d_free(pn_distribution2d *d) {
    free(d);
}
