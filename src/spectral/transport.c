/* transport.c — spectral mode's wavelengths and conversions (transport.h). */
#include "spectral/transport.h"

#include "spectral/cie.h"
#include "spectral/rgb2spec.h"
#include "spectral/wavelengths.h"

#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>

/* 1 / luminance of the tabulated D65 (the factor that makes its Y 1), and 1 / (integral of
 * y-bar): set once. The luminance is the integral of the product of the two interpolated tables
 * (trapezoid rule at 0.25 nm, exact to 1e-6 for these piecewise linear functions), the quantity
 * the film's estimator is unbiased for. */
static double g_d65_scale, g_inv_y_integral;
static pthread_once_t g_once = PTHREAD_ONCE_INIT;

static void transport_init(void) {
    double yint = pn_cie_y_integral(), sum = 0.0;
    const double h = 0.25;
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX + 1e-9; l += h) {
        double w = (l == PN_LAMBDA_MIN || l > PN_LAMBDA_MAX - 1e-9) ? 0.5 * h : h;
        double bar[3];
        pn_cie_xyz_bar(l, bar);
        sum += w * bar[1] * pn_cie_table_eval(pn_cie_d65_5nm, l);
    }
    g_d65_scale = yint / sum;
    g_inv_y_integral = 1.0 / yint;
}

double pn_swl_d65(double lambda) {
    pthread_once(&g_once, transport_init);
    return g_d65_scale * pn_cie_table_eval(pn_cie_d65_5nm, lambda);
}

void pn_swl_sample(float u, pn_swl *out) {
    pthread_once(&g_once, transport_init);
    /* The film's maps (transport.h): the CIE lookups once per set of wavelengths, not per value
     * converted (illumcut converts one value per cluster pair of Phase I). */
    const double k = g_inv_y_integral / PN_SWL_COUNT;
    for (int i = 0; i < PN_SWL_COUNT; i++) {
        double ui = (double)u + (double)i / PN_SWL_COUNT;
        if (ui >= 1.0) ui -= 1.0;
        double lambda, inv_pdf;
        pn_visible_wavelength_sample_inv_pdf(ui, &lambda, &inv_pdf);
        out->lambda[i] = (float)lambda;
        out->inv_pdf[i] = (float)inv_pdf;
        out->illum[i] = (float)(g_d65_scale * pn_cie_table_eval(pn_cie_d65_5nm, lambda));
        double bar[3], xyz[3], rgb[3];
        pn_cie_xyz_bar(out->lambda[i], bar);
        for (int c = 0; c < 3; c++) xyz[c] = bar[c] * (double)out->inv_pdf[i] * k;
        pn_xyz_to_linear_srgb(xyz, rgb);
        for (int c = 0; c < 3; c++) {
            out->xyz_w[c][i] = (float)xyz[c];
            out->rgb_w[c][i] = (float)rgb[c];
        }
    }
    out->memo = NULL;
    out->on = true;
}

/* The sigmoid-polynomial spectrum of coefficients c at the wavelengths, in float as pbrt-v4. */
static float sigmoid_at(const float c[3], float lambda) {
    float x = (c[0] * lambda + c[1]) * lambda + c[2];
    if (isinf(x)) return x > 0.0f ? 1.0f : 0.0f;
    return 0.5f + x / (2.0f * sqrtf(1.0f + x * x));
}

/* Comparisons rather than fmaxf and fminf, which this build calls in libm: the same result for
 * every input (NaN gives 0 as fmaxf(NaN, 0) does; -0 gives +0, which compares equal). */
static inline float clamp_nonneg(float x) {
    return x > 0.0f ? x : 0.0f;
}
static inline float clamp01(float x) {
    return x > 0.0f ? (x < 1.0f ? x : 1.0f) : 0.0f;
}

static inline uint32_t float_bits(float x) {
    union {
        float f;
        uint32_t u;
    } b = {x};
    return b.u;
}

static inline uint32_t key_hash(const uint32_t key[3]) {
    uint32_t h = (key[0] * 73856093u) ^ (key[1] * 19349663u) ^ (key[2] * 83492791u);
    return h ^ (h >> 11);
}

/* Reflectances: a per-thread table (direct-mapped by the clamped rgb's bits) of the last sigmoid
 * coefficients looked up. ias evaluates each shading point's kd and ks once per light sample, at
 * that sample's own wavelengths, so the lookup (the trilinear interpolation of 24 table values and
 * the binary search for z) would otherwise repeat for every sample of a point. The coefficients
 * are the table's for exactly that rgb, so the result does not depend on the table's state. */
#define PN_ALBEDO_CACHE 64

typedef struct albedo_entry {
    uint32_t key[3];
    float c[3];
    bool used;
} albedo_entry;

static _Thread_local albedo_entry g_albedo_cache[PN_ALBEDO_CACHE];

vec3 pn_swl_albedo_on(const pn_swl *w, vec3 rgb) {
    float r = clamp01(rgb.x), g = clamp01(rgb.y), b = clamp01(rgb.z);
    if (r == g && g == b) return v3(r, r, r);
    const uint32_t key[3] = {float_bits(r), float_bits(g), float_bits(b)};
    albedo_entry *e = &g_albedo_cache[key_hash(key) % PN_ALBEDO_CACHE];
    if (!(e->used && e->key[0] == key[0] && e->key[1] == key[1] && e->key[2] == key[2])) {
        const float c[3] = {r, g, b};
        pn_rgb2spec_lookup(pn_rgb2spec_srgb(), c, e->c);
        for (int i = 0; i < 3; i++) e->key[i] = key[i];
        e->used = true;
    }
    return v3(sigmoid_at(e->c, w->lambda[0]), sigmoid_at(e->c, w->lambda[1]), sigmoid_at(e->c, w->lambda[2]));
}

/* The spectrum of an unbounded colour, rgb / (2 max), is looked up with its components rounded to
 * multiples of 2^-16 (a change of at most 8e-6 in the table's input, far below its 1e-3
 * interpolation error), so that the VPLs and light samples of one light, whose RGB differ only by
 * a scalar (and so in the last bits of rgb / (2 max)), share one key. A per-thread table
 * (two-way set-associative by the key) remembers the sigmoid coefficients of the last keys, and
 * with them the spectrum's values at the last wavelengths they were evaluated at: the VPL
 * integrators upsample thousands of intensities of a few hundred colours at one receiver's
 * wavelengths, so most evaluations are a comparison (illumcut, whose order changes the
 * wavelengths from one evaluation to the next, still saves the table lookup). Coefficients and
 * values are functions of the key and the wavelengths only, whether they come from the table or
 * not, so images do not depend on the thread count or the order of evaluation. */
#define PN_UNBOUNDED_QUANTUM 65536.0f
#define PN_UNBOUNDED_SETS 512

typedef struct unbounded_entry {
    uint32_t key[3];
    float c[3];
    float lambda[PN_SWL_COUNT], value[PN_SWL_COUNT]; /* the spectrum at lambda (lambda[0] 0: none) */
    bool used, recent;                               /* recent: the set's last entry used */
} unbounded_entry;

static _Thread_local unbounded_entry g_unbounded_cache[PN_UNBOUNDED_SETS][2];

static vec3 unbounded_unit(const pn_swl *w, const uint32_t key[3]) {
    unbounded_entry *set = g_unbounded_cache[key_hash(key) % PN_UNBOUNDED_SETS];
    unbounded_entry *e = NULL;
    for (int k = 0; k < 2; k++)
        if (set[k].used && set[k].key[0] == key[0] && set[k].key[1] == key[1] && set[k].key[2] == key[2]) e = &set[k];
    if (!e) {
        e = set[0].recent ? &set[1] : &set[0]; /* replace the less recently used */
        const float rgb[3] = {(float)key[0] / PN_UNBOUNDED_QUANTUM, (float)key[1] / PN_UNBOUNDED_QUANTUM,
                              (float)key[2] / PN_UNBOUNDED_QUANTUM};
        pn_rgb2spec_lookup(pn_rgb2spec_srgb(), rgb, e->c);
        for (int i = 0; i < 3; i++) e->key[i] = key[i];
        e->lambda[0] = 0.0f;
        e->used = true;
    }
    set[0].recent = e == &set[0];
    set[1].recent = e == &set[1];
    if (!(e->lambda[0] == w->lambda[0] && e->lambda[1] == w->lambda[1] && e->lambda[2] == w->lambda[2])) {
        for (int i = 0; i < PN_SWL_COUNT; i++) {
            e->lambda[i] = w->lambda[i];
            e->value[i] = sigmoid_at(e->c, w->lambda[i]);
        }
    }
    return v3(e->value[0], e->value[1], e->value[2]);
}

/* ---- the memo (transport.h) --------------------------------------------------------------- */

/* Rows by colour key in an open-addressing table of twice the row limit (a power of two), and
 * the last row used, since consecutive conversions are mostly of one colour. A row holds
 * PN_SWL_COUNT values per receiver, -1 (no sigmoid value) until computed. */
struct pn_swl_memo {
    int32_t receivers, rows, max_rows;
    uint32_t mask;
    uint32_t (*key)[3]; /* mask + 1 */
    int32_t *row_of;    /* mask + 1: row index, -1 empty */
    float **row;        /* max_rows */
    int32_t last;       /* last row used, -1 none */
};

pn_swl_memo *pn_swl_memo_new(int32_t receivers, size_t max_bytes) {
    if (receivers < 1) return NULL;
    pn_swl_memo *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    size_t row_bytes = (size_t)receivers * PN_SWL_COUNT * sizeof(float);
    size_t rows = max_bytes / row_bytes;
    if (rows < 16) rows = 16;
    if (rows > 4096) rows = 4096;
    uint32_t size = 32;
    while (size < 2 * rows) size *= 2;
    m->receivers = receivers;
    m->max_rows = (int32_t)rows;
    m->mask = size - 1;
    m->last = -1;
    m->key = malloc(size * sizeof *m->key);
    m->row_of = malloc(size * sizeof *m->row_of);
    m->row = calloc(rows, sizeof *m->row);
    if (!m->key || !m->row_of || !m->row) {
        pn_swl_memo_free(m);
        return NULL;
    }
    for (uint32_t i = 0; i < size; i++) m->row_of[i] = -1;
    return m;
}

void pn_swl_memo_free(pn_swl_memo *m) {
    if (!m) return;
    if (m->row)
        for (int32_t i = 0; i < m->rows; i++) free(m->row[i]);
    free(m->row);
    free(m->key);
    free(m->row_of);
    free(m);
}

/* The row of key (made if new); NULL when the memo is full or out of memory. */
static float *memo_row(pn_swl_memo *m, const uint32_t key[3]) {
    if (m->last >= 0) {
        const uint32_t *k = m->key[m->last];
        if (k[0] == key[0] && k[1] == key[1] && k[2] == key[2]) return m->row[m->row_of[m->last]];
    }
    uint32_t h = key_hash(key) & m->mask;
    while (m->row_of[h] >= 0) {
        const uint32_t *k = m->key[h];
        if (k[0] == key[0] && k[1] == key[1] && k[2] == key[2]) {
            m->last = (int32_t)h;
            return m->row[m->row_of[h]];
        }
        h = (h + 1) & m->mask;
    }
    if (m->rows == m->max_rows) return NULL;
    size_t n = (size_t)m->receivers * PN_SWL_COUNT;
    float *r = malloc(n * sizeof *r);
    if (!r) return NULL;
    for (size_t i = 0; i < n; i++) r[i] = -1.0f;
    m->row[m->rows] = r;
    m->row_of[h] = m->rows++;
    for (int i = 0; i < 3; i++) m->key[h][i] = key[i];
    m->last = (int32_t)h;
    return r;
}

/* unbounded_unit through w's memo. */
static vec3 memo_unit(const pn_swl *w, const uint32_t key[3]) {
    float *row = memo_row(w->memo, key);
    if (!row) return unbounded_unit(w, key);
    float *v = row + (size_t)w->memo_index * PN_SWL_COUNT;
    if (v[0] < 0.0f) {
        vec3 u = unbounded_unit(w, key);
        v[0] = u.x;
        v[1] = u.y;
        v[2] = u.z;
    }
    return v3(v[0], v[1], v[2]);
}

vec3 pn_swl_unbounded_on(const pn_swl *w, vec3 rgb) {
    float r = clamp_nonneg(rgb.x), g = clamp_nonneg(rgb.y), b = clamp_nonneg(rgb.z);
    float m = r > g ? r : g;
    m = m > b ? m : b;
    if (!(m > 0.0f) || !isfinite(m)) return v3(0, 0, 0);
    if (r == g && g == b) return v3(r, r, r);
    float scale = 2.0f * m, inv = PN_UNBOUNDED_QUANTUM / scale;
    const uint32_t key[3] = {(uint32_t)(r * inv + 0.5f), (uint32_t)(g * inv + 0.5f), (uint32_t)(b * inv + 0.5f)};
    return v3_scale(w->memo ? memo_unit(w, key) : unbounded_unit(w, key), scale);
}

vec3 pn_swl_illuminant_on(const pn_swl *w, vec3 rgb) {
    vec3 s = pn_swl_unbounded_on(w, rgb);
    return v3(s.x * w->illum[0], s.y * w->illum[1], s.z * w->illum[2]);
}

/* A 3 x 3 map of the values at the wavelengths, accumulated in double. */
static inline vec3 swl_map(const float m[3][PN_SWL_COUNT], vec3 v) {
    const double a = v.x, b = v.y, c = v.z;
    double out[3];
    for (int k = 0; k < 3; k++) out[k] = (double)m[k][0] * a + (double)m[k][1] * b + (double)m[k][2] * c;
    return v3((float)out[0], (float)out[1], (float)out[2]);
}

vec3 pn_swl_xyz_on(const pn_swl *w, vec3 v) {
    return swl_map(w->xyz_w, v);
}

vec3 pn_swl_rgb_on(const pn_swl *w, vec3 v) {
    return swl_map(w->rgb_w, v);
}

double pn_blackbody_unit_scale(double kelvin) {
    if (!(kelvin > 0.0)) return 0.0;
    double sum = 0.0;
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += 1.0) {
        double bar[3];
        pn_cie_xyz_bar(l, bar);
        sum += (l == PN_LAMBDA_MIN || l == PN_LAMBDA_MAX ? 0.5 : 1.0) * bar[1] * pn_planck(l, kelvin);
    }
    return sum > 0.0 ? pn_cie_y_integral() / sum : 0.0;
}

vec3 pn_swl_blackbody(const pn_swl *w, float kelvin, float unit_scale, vec3 rgb) {
    if (!pn_swl_active(w)) return rgb;
    double k = (double)v3_luminance(rgb) * (double)unit_scale;
    return v3((float)(k * pn_planck(w->lambda[0], kelvin)), (float)(k * pn_planck(w->lambda[1], kelvin)),
              (float)(k * pn_planck(w->lambda[2], kelvin)));
}

/* ---- tabulated emission spectra ---------------------------------------------------------- */

double pn_table_eval(const double *lambda_nm, const double *value, int n, double lambda) {
    if (lambda <= lambda_nm[0]) return value[0];
    if (lambda >= lambda_nm[n - 1]) return value[n - 1];
    int lo = 0, hi = n - 1; /* lambda_nm[lo] <= lambda < lambda_nm[hi] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (lambda_nm[mid] <= lambda)
            lo = mid;
        else
            hi = mid;
    }
    double t = (lambda - lambda_nm[lo]) / (lambda_nm[hi] - lambda_nm[lo]);
    return value[lo] * (1.0 - t) + value[hi] * t;
}

double pn_spd_eval(const pn_spd *s, double lambda) {
    return pn_table_eval(s->lambda, s->value, s->count, lambda);
}

void pn_spd_free(pn_spd *s) {
    if (!s) return;
    free(s->lambda);
    free(s->value);
    free(s);
}

pn_spd *pn_spd_new(const double *pairs, int count) {
    if (count < 1) return NULL;
    pn_spd *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->count = count;
    s->lambda = malloc((size_t)count * sizeof *s->lambda);
    s->value = malloc((size_t)count * sizeof *s->value);
    if (!s->lambda || !s->value) {
        pn_spd_free(s);
        return NULL;
    }
    for (int i = 0; i < count; i++) {
        s->lambda[i] = pairs[2 * i];
        s->value[i] = pairs[2 * i + 1];
    }
    /* Luminance as the film integrates it: ∫ ȳ S / ∫ ȳ, trapezoid rule at 0.1 nm (narrow lines of
     * a few nm are resolved; the error is below 1e-5 for lines 1 nm wide). */
    const double h = 0.1;
    const int steps = (int)((PN_LAMBDA_MAX - PN_LAMBDA_MIN) / h + 0.5);
    double sum = 0.0;
    for (int k = 0; k <= steps; k++) {
        double l = PN_LAMBDA_MIN + h * k, bar[3];
        pn_cie_xyz_bar(l, bar);
        sum += (k == 0 || k == steps ? 0.5 * h : h) * bar[1] * pn_spd_eval(s, l);
    }
    double y = sum / pn_cie_y_integral();
    s->scale = y > 0.0 && isfinite(y) ? 1.0 / y : 0.0; /* no luminance: black, as in RGB mode */
    return s;
}

vec3 pn_swl_tabulated(const pn_swl *w, const pn_spd *s, vec3 rgb) {
    if (!pn_swl_active(w)) return rgb;
    double k = (double)v3_luminance(rgb) * s->scale;
    return v3((float)(k * pn_spd_eval(s, w->lambda[0])), (float)(k * pn_spd_eval(s, w->lambda[1])),
              (float)(k * pn_spd_eval(s, w->lambda[2])));
}
