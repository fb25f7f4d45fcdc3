/* rgb2spec.c — the sigmoid-polynomial fit and its table (rgb2spec.h).
 *
 * Parts, in the order of the paper (Jakob & Hanika 2019, §3–4):
 *  - quadrature: the CIE 1931 matching functions weighted by D65, on a Simpson rule of 2.5 nm
 *    steps over 360–830 nm, normalised so that the perfect white reflector has Y = 1;
 *  - residual: CIELAB difference between the target colour and the spectrum's colour (the paper
 *    fits in CIELAB so that the error is perceptually even across the cube);
 *  - Gauss–Newton: an analytic Jacobian (sigmoid, XYZ and CIELAB chain rule) and a 3×3 solve per step, coefficients kept within
 *    ±200 in the normalised domain (beyond that the sigmoid is a step and the fit only drifts);
 *  - table: for each largest component, z (its value, on nodes dense near 0 and 1:
 *    smoothstep(smoothstep(u))) × the two others divided by it; fits along z start from z = 0.2
 *    and warm-start each from its neighbour, outwards in both directions;
 *  - lookup: trilinear interpolation of the coefficients (the paper's, and pbrt-v4's, choice;
 *    interpolating coefficients, not spectra, keeps the lookup three multiply-adds per value).
 */
#include "spectral/rgb2spec.h"

#include "spectral/cie.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* 2.5 nm steps: Simpson's rule is then exact on each 5 nm piece of D65 × x̄ȳz̄ (a quadratic), so
 * only the sigmoid's curvature is approximated (round trips to 1 nm integration within 4e-5). */
#define QUAD_INTERVALS 188
#define QUAD_NODES (QUAD_INTERVALS + 1)
#define COEFF_LIMIT 200.0

/* ---- quadrature --------------------------------------------------------------------------- */

typedef struct quadrature {
    double t[QUAD_NODES];        /* normalised wavelength (λ - 360) / 470 */
    double w_xyz[QUAD_NODES][3]; /* Simpson weight × x̄ȳz̄ × D65, normalised: white has Y = 1 */
    double white_xyz[3];
} quadrature;

static quadrature g_quad;
static pthread_once_t g_quad_once = PTHREAD_ONCE_INIT;

static void quad_init(void) {
    const double h = (PN_LAMBDA_MAX - PN_LAMBDA_MIN) / QUAD_INTERVALS;
    double y_sum = 0.0;
    for (int k = 0; k < QUAD_NODES; k++) {
        double lambda = PN_LAMBDA_MIN + k * h;
        double simpson = (k == 0 || k == QUAD_NODES - 1) ? 1.0 : (k % 2 ? 4.0 : 2.0);
        double bar[3];
        pn_cie_xyz_bar(lambda, bar);
        double w = simpson * h / 3.0 * pn_cie_table_eval(pn_cie_d65_5nm, lambda);
        g_quad.t[k] = (lambda - PN_LAMBDA_MIN) / (PN_LAMBDA_MAX - PN_LAMBDA_MIN);
        for (int c = 0; c < 3; c++) g_quad.w_xyz[k][c] = w * bar[c];
        y_sum += w * bar[1];
    }
    g_quad.white_xyz[0] = g_quad.white_xyz[1] = g_quad.white_xyz[2] = 0.0;
    for (int k = 0; k < QUAD_NODES; k++)
        for (int c = 0; c < 3; c++) {
            g_quad.w_xyz[k][c] /= y_sum;
            g_quad.white_xyz[c] += g_quad.w_xyz[k][c];
        }
}

static const quadrature *quad(void) {
    pthread_once(&g_quad_once, quad_init);
    return &g_quad;
}

/* ---- residual and Gauss–Newton ----------------------------------------------------------- */

/* The derivative of CIE 1976's f(t), for the chain rule of the Jacobian. */
static double lab_f_prime(double t) {
    const double d = 6.0 / 29.0;
    if (t > d * d * d) {
        double r = cbrt(t);
        return 1.0 / (3.0 * r * r);
    }
    return 1.0 / (3.0 * d * d);
}

/* CIELAB of the reflectance of normalised coefficients c, and its Jacobian d lab / d c
 * (analytic: S'(x) = 1 / (2 (1 + x²)^{3/2}), then the chain rule through XYZ and f). */
static void spectrum_lab(const quadrature *q, const double c[3], double lab[3], double jac[3][3]) {
    double xyz[3] = {0.0, 0.0, 0.0}, dxyz[3][3] = {{0.0}}; /* dxyz[j][i] = d XYZ_j / d c_i */
    for (int k = 0; k < QUAD_NODES; k++) {
        double t = q->t[k];
        double x = (c[0] * t + c[1]) * t + c[2];
        /* S(x) = 1/2 + x sqrt(r) / 2 and S'(x) = r sqrt(r) / 2 with r = 1 / (1 + x²): one division
         * and one square root per node (the fit's inner loop). */
        double r = 1.0 / (1.0 + x * x), root = sqrt(r);
        double s = 0.5 + 0.5 * x * root;
        double ds = 0.5 * r * root;
        double basis[3] = {t * t, t, 1.0};
        for (int j = 0; j < 3; j++) {
            xyz[j] += s * q->w_xyz[k][j];
            for (int i = 0; i < 3; i++) dxyz[j][i] += ds * basis[i] * q->w_xyz[k][j];
        }
    }
    pn_xyz_to_lab(xyz, q->white_xyz, lab);
    double dfx[3], dfy[3], dfz[3]; /* d f(XYZ_j / white_j) / d c_i */
    double gx = lab_f_prime(xyz[0] / q->white_xyz[0]) / q->white_xyz[0];
    double gy = lab_f_prime(xyz[1] / q->white_xyz[1]) / q->white_xyz[1];
    double gz = lab_f_prime(xyz[2] / q->white_xyz[2]) / q->white_xyz[2];
    for (int i = 0; i < 3; i++) {
        dfx[i] = gx * dxyz[0][i];
        dfy[i] = gy * dxyz[1][i];
        dfz[i] = gz * dxyz[2][i];
        jac[0][i] = 116.0 * dfy[i];
        jac[1][i] = 500.0 * (dfx[i] - dfy[i]);
        jac[2][i] = 200.0 * (dfy[i] - dfz[i]);
    }
}

/* Solves the 3×3 system a x = b by Gaussian elimination with partial pivoting; false if singular. */
static bool solve3(double a[3][3], double b[3], double x[3]) {
    for (int col = 0; col < 3; col++) {
        int pivot = col;
        for (int r = col + 1; r < 3; r++)
            if (fabs(a[r][col]) > fabs(a[pivot][col])) pivot = r;
        if (fabs(a[pivot][col]) < 1e-15) return false;
        if (pivot != col) {
            for (int k = 0; k < 3; k++) {
                double tmp = a[col][k];
                a[col][k] = a[pivot][k];
                a[pivot][k] = tmp;
            }
            double tmp = b[col];
            b[col] = b[pivot];
            b[pivot] = tmp;
        }
        for (int r = col + 1; r < 3; r++) {
            double f = a[r][col] / a[col][col];
            for (int k = col; k < 3; k++) a[r][k] -= f * a[col][k];
            b[r] -= f * b[col];
        }
    }
    for (int r = 2; r >= 0; r--) {
        double s = b[r];
        for (int k = r + 1; k < 3; k++) s -= a[r][k] * x[k];
        x[r] = s / a[r][r];
    }
    return true;
}

double pn_rgb2spec_fit(const double rgb[3], double c[3]) {
    const quadrature *q = quad();
    double target_xyz[3], target_lab[3];
    pn_linear_srgb_to_xyz(rgb, target_xyz);
    pn_xyz_to_lab(target_xyz, q->white_xyz, target_lab);
    double residual_norm = INFINITY;
    for (int iteration = 0; iteration < 15; iteration++) {
        double lab[3], r[3], jac[3][3];
        spectrum_lab(q, c, lab, jac);
        for (int j = 0; j < 3; j++) r[j] = lab[j] - target_lab[j];
        residual_norm = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        if (residual_norm < 1e-6) break;
        double step[3];
        if (!solve3(jac, r, step)) break;
        double biggest = 0.0;
        for (int i = 0; i < 3; i++) {
            c[i] -= step[i];
            biggest = fmax(biggest, fabs(c[i]));
        }
        if (biggest > COEFF_LIMIT)
            for (int i = 0; i < 3; i++) c[i] *= COEFF_LIMIT / biggest;
    }
    return residual_norm;
}

void pn_rgb2spec_to_nm(const double cn[3], float c_nm[3]) {
    const double a = PN_LAMBDA_MIN, w = PN_LAMBDA_MAX - PN_LAMBDA_MIN;
    c_nm[0] = (float)(cn[0] / (w * w));
    c_nm[1] = (float)(cn[1] / w - 2.0 * a * cn[0] / (w * w));
    c_nm[2] = (float)(cn[0] * a * a / (w * w) - cn[1] * a / w + cn[2]);
}

/* ---- table --------------------------------------------------------------------------------- */

static double smoothstep(double x) {
    return x * x * (3.0 - 2.0 * x);
}

static size_t cell_index(int res, int l, int zi, int yi, int xi) {
    return ((((size_t)l * res + zi) * res + yi) * res + xi) * 3;
}

/* One row of the table: a largest component l and a (x, y) cell, fitted along z. */
static void fit_column(pn_rgb2spec_table *table, int l, int yi, int xi) {
    const int res = table->res, start = res / 5;
    double x = xi / (double)(res - 1), y = yi / (double)(res - 1);
    for (int pass = 0; pass < 2; pass++) {
        double c[3] = {0.0, 0.0, 0.0};
        int from = pass == 0 ? start : start - 1, to = pass == 0 ? res : -1, dir = pass == 0 ? 1 : -1;
        for (int zi = from; zi != to; zi += dir) {
            double z = table->z_nodes[zi], rgb[3];
            rgb[l] = z;
            rgb[(l + 1) % 3] = x * z;
            rgb[(l + 2) % 3] = y * z;
            pn_rgb2spec_fit(rgb, c);
            pn_rgb2spec_to_nm(c, table->coeffs + cell_index(res, l, zi, yi, xi));
        }
    }
}

typedef struct build_job {
    pn_rgb2spec_table *table;
    int first, step; /* rows (l, yi) first, first + step, ... */
} build_job;

static void *build_rows(void *arg) {
    build_job *job = arg;
    const int res = job->table->res;
    for (int row = job->first; row < 3 * res; row += job->step)
        for (int xi = 0; xi < res; xi++) fit_column(job->table, row / res, row % res, xi);
    return NULL;
}

bool pn_rgb2spec_table_build(pn_rgb2spec_table *table, int res, int threads) {
    memset(table, 0, sizeof(*table));
    if (res < 3) return false;
    table->res = res;
    table->z_nodes = malloc(sizeof(float) * (size_t)res);
    table->coeffs = malloc(sizeof(float) * 9 * (size_t)res * res * res);
    if (!table->z_nodes || !table->coeffs) {
        pn_rgb2spec_table_free(table);
        return false;
    }
    for (int i = 0; i < res; i++) table->z_nodes[i] = (float)smoothstep(smoothstep(i / (double)(res - 1)));
    if (threads < 1) threads = 1;
    if (threads > 64) threads = 64;
    /* Each cell is fitted from the same start along the same path whatever the thread count, so
     * the table is identical for any number of threads. */
    build_job jobs[64];
    pthread_t ids[64];
    bool created[64] = {false};
    for (int t = 0; t < threads; t++) jobs[t] = (build_job){table, t, threads};
    for (int t = 1; t < threads; t++) created[t] = pthread_create(&ids[t], NULL, build_rows, &jobs[t]) == 0;
    for (int t = 0; t < threads; t++)
        if (!created[t]) build_rows(&jobs[t]); /* job 0, and any whose thread could not start */
    for (int t = 1; t < threads; t++)
        if (created[t]) pthread_join(ids[t], NULL);
    return true;
}

void pn_rgb2spec_table_free(pn_rgb2spec_table *table) {
    free(table->z_nodes);
    free(table->coeffs);
    memset(table, 0, sizeof(*table));
}

void pn_rgb2spec_lookup(const pn_rgb2spec_table *table, const float rgb_in[3], float c[3]) {
    float rgb[3];
    for (int i = 0; i < 3; i++) rgb[i] = fminf(fmaxf(rgb_in[i], 0.0f), 1.0f);
    if (rgb[0] == rgb[1] && rgb[1] == rgb[2]) {
        /* Grey: a constant spectrum, S(c2) = value exactly. */
        double v = rgb[0];
        c[0] = c[1] = 0.0f;
        c[2] = v <= 0.0 ? -INFINITY : v >= 1.0 ? INFINITY : (float)((v - 0.5) / sqrt(v * (1.0 - v)));
        return;
    }
    int l = rgb[0] >= rgb[1] ? (rgb[0] >= rgb[2] ? 0 : 2) : (rgb[1] >= rgb[2] ? 1 : 2);
    const int res = table->res;
    float z = rgb[l];
    float x = rgb[(l + 1) % 3] * (res - 1) / z, y = rgb[(l + 2) % 3] * (res - 1) / z;
    /* The z interval: the last node <= z (binary search on the increasing nodes). */
    int lo = 0, hi = res - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (table->z_nodes[mid] <= z)
            lo = mid;
        else
            hi = mid;
    }
    int zi = lo;
    float tz = (z - table->z_nodes[zi]) / (table->z_nodes[zi + 1] - table->z_nodes[zi]);
    int xi = (int)x < res - 2 ? (int)x : res - 2, yi = (int)y < res - 2 ? (int)y : res - 2;
    float tx = x - xi, ty = y - yi;
    for (int k = 0; k < 3; k++) {
        float v = 0.0f;
        for (int dz = 0; dz < 2; dz++)
            for (int dy = 0; dy < 2; dy++)
                for (int dx = 0; dx < 2; dx++) {
                    float w = (dz ? tz : 1.0f - tz) * (dy ? ty : 1.0f - ty) * (dx ? tx : 1.0f - tx);
                    v += w * table->coeffs[cell_index(res, l, zi + dz, yi + dy, xi + dx) + k];
                }
        c[k] = v;
    }
}

void pn_rgb2spec_reflectance_rgb(const float c[3], double rgb[3]) {
    double xyz[3] = {0.0, 0.0, 0.0}, y_white = 0.0;
    for (double lambda = PN_LAMBDA_MIN; lambda <= PN_LAMBDA_MAX; lambda += 1.0) {
        double w = (lambda == PN_LAMBDA_MIN || lambda == PN_LAMBDA_MAX ? 0.5 : 1.0) *
                   pn_cie_table_eval(pn_cie_d65_5nm, lambda);
        double bar[3];
        pn_cie_xyz_bar(lambda, bar);
        double s = pn_sigmoid_spectrum(c, lambda);
        for (int j = 0; j < 3; j++) xyz[j] += w * bar[j] * s;
        y_white += w * bar[1];
    }
    for (int j = 0; j < 3; j++) xyz[j] /= y_white;
    pn_xyz_to_linear_srgb(xyz, rgb);
}
