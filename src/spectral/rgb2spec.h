/* rgb2spec.h — RGB to spectrum upsampling by the sigmoid-polynomial model of Jakob and Hanika,
 * "A Low-Dimensional Function Space for Efficient Spectral Upsampling", Computer Graphics Forum
 * 38(2), 2019 (the model pbrt-v4 uses for every RGB value of a scene).
 *
 * A reflectance spectrum is s(λ) = S(c0 λ² + c1 λ + c2) with S(x) = 1/2 + x / (2 √(1 + x²)): smooth,
 * bounded to [0, 1], and three coefficients per colour. The coefficients of a linear sRGB colour are
 * found by Gauss–Newton iteration on the CIELAB difference between the colour and the spectrum's
 * colour as a reflectance under the colour space's illuminant (D65 for sRGB). A table over the RGB
 * cube (indexed by the largest component and the two others relative to it) holds precomputed
 * coefficients; lookups interpolate them trilinearly, as the paper does.
 */
#ifndef PN_SPECTRAL_RGB2SPEC_H
#define PN_SPECTRAL_RGB2SPEC_H

#include <stdbool.h>
#include <stddef.h>

/* S(x); S(±inf) = 1 or 0 (the coefficients of black and white are infinite). */
static inline double pn_sigmoid(double x) {
    if (x > 1e18) return 1.0;
    if (x < -1e18) return 0.0;
    return 0.5 + x / (2.0 * __builtin_sqrt(1.0 + x * x));
}

/* The spectrum of coefficients c (for λ in nm) at lambda. */
static inline double pn_sigmoid_spectrum(const float c[3], double lambda) {
    return pn_sigmoid(((double)c[0] * lambda + (double)c[1]) * lambda + (double)c[2]);
}

/* Fits the coefficients of the reflectance with linear sRGB rgb (components in [0, 1]).
 * c_normalised holds the start on entry and the result on return, for the polynomial in
 * t = (λ - 360) / 470 (the optimiser's domain; pn_rgb2spec_to_nm converts). Returns the final
 * CIELAB difference ΔE*ab. */
double pn_rgb2spec_fit(const double rgb[3], double c_normalised[3]);

/* Converts coefficients of the polynomial in t = (λ - 360) / 470 to the polynomial in λ (nm). */
void pn_rgb2spec_to_nm(const double c_normalised[3], float c_nm[3]);

/* The table: res³ cells for each of the three choices of the largest component. */
typedef struct pn_rgb2spec_table {
    int res;
    float *z_nodes; /* res values of the largest component, dense near 0 and 1 */
    float *coeffs;  /* [3][res (z)][res (y)][res (x)][3], polynomial in λ (nm) */
} pn_rgb2spec_table;

/* Builds the table at resolution res (>= 3) on `threads` threads (the result does not depend on
 * their number). false when out of memory. */
bool pn_rgb2spec_table_build(pn_rgb2spec_table *table, int res, int threads);

/* The table of linear sRGB, generated at build time (tools/rgb2spec_gen.c) at resolution 64 and
 * linked into the library. */
const pn_rgb2spec_table *pn_rgb2spec_srgb(void);
void pn_rgb2spec_table_free(pn_rgb2spec_table *table);

/* Coefficients of the reflectance of linear sRGB rgb (clamped to [0, 1]), from the table. */
void pn_rgb2spec_lookup(const pn_rgb2spec_table *table, const float rgb[3], float c[3]);

/* The linear sRGB of a reflectance spectrum of coefficients c under D65 (the round trip of the
 * fit; integrated at 1 nm). */
void pn_rgb2spec_reflectance_rgb(const float c[3], double rgb[3]);

#endif
