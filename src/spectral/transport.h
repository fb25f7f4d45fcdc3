/* transport.h — what an eye sample carries in spectral mode (--spectral) and the conversions at the
 * points of use, after pbrt-v4 (SampledWavelengths, RGBAlbedoSpectrum, RGBUnboundedSpectrum,
 * RGBIlluminantSpectrum, RGBFilm with the "cie1931" sensor).
 *
 * An eye sample draws PN_SWL_COUNT = 3 wavelengths (a hero and two companions stratified in the
 * CDF of wavelengths.h's density), and every vec3 of its path then holds values at those three
 * wavelengths instead of R, G and B: the existing vec3 arithmetic of every integrator carries them
 * unchanged. pbrt-v4 carries 4; 3 is what a vec3 holds, and a fourth would need a second type
 * through every integrator (measured cost and noise: docs/spectral.md).
 *
 * Only the places where a colour enters the path convert, each through one of:
 *   albedo      a reflectance (kd, ks, specular tints): rgb clamped to [0, 1], the
 *               sigmoid-polynomial spectrum of rgb2spec.h;
 *   unbounded   an unbounded value (conductor eta, k): 2 max(rgb) times the spectrum of
 *               rgb / (2 max(rgb));
 *   illuminant  an emission (area lights, light samples, environment texels, VPL intensities):
 *               the unbounded spectrum times the colour space's illuminant, D65 normalised to
 *               luminance 1 as pbrt-v4 normalises it (so white (1,1,1) emits D65 of Y = 1);
 * and the value an eye sample adds to its pixel is turned back into linear sRGB by
 *     XYZ = (1 / n) sum_i cmf(lambda_i) L(lambda_i) / pdf(lambda_i) / (integral of y-bar)
 * (pbrt-v4's PixelSensor::ToSensorRGB for the CIE 1931 sensor, then XYZ -> sRGB).
 *
 * Every function takes the wavelengths as a pointer that is NULL (or not `on`) in RGB mode, where
 * it returns its argument unchanged: RGB mode's arithmetic is untouched, bit for bit.
 *
 * A shortcut, exact in the model: grey reflectances and grey emissions (r = g = b) are constant
 * spectra, so they skip the table (the sigmoid of a constant is that constant). */
#ifndef PN_SPECTRAL_TRANSPORT_H
#define PN_SPECTRAL_TRANSPORT_H

#include "core/vecmath.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define PN_SWL_COUNT 3

struct pn_swl_memo;

typedef struct pn_swl {
    float lambda[PN_SWL_COUNT];  /* nm */
    float inv_pdf[PN_SWL_COUNT]; /* 1 / (density of each wavelength alone, per nm) */
    float illum[PN_SWL_COUNT];   /* the illuminant (D65, luminance 1) at lambda */
    /* The film's estimator as two 3 x 3 maps of the values at the wavelengths, set by
     * pn_swl_sample so that a conversion costs 9 multiply-adds and no CIE table lookup:
     * xyz_w[k][i] = cmf_k(lambda_i) / pdf(lambda_i) / (n * integral of y-bar), and rgb_w the
     * XYZ -> linear sRGB matrix times xyz_w. */
    float xyz_w[3][PN_SWL_COUNT];
    float rgb_w[3][PN_SWL_COUNT];
    /* Optional: a memo of unbounded spectra with a slot for these wavelengths
     * (pn_swl_memo_attach); NULL after pn_swl_sample. */
    struct pn_swl_memo *memo;
    int32_t memo_index;
    bool on;
} pn_swl;

/* The wavelengths of uniform u in [0, 1): the hero at u, companions at u + 1/3, u + 2/3 (mod 1). */
void pn_swl_sample(float u, pn_swl *out);

static inline bool pn_swl_active(const pn_swl *w) {
    return w && w->on;
}

/* The conversions for active wavelengths (w->on); the wrappers below call them in spectral mode
 * only. pn_swl_xyz_on is the film's XYZ of a value at the wavelengths (see the header). */
vec3 pn_swl_albedo_on(const pn_swl *w, vec3 rgb);
vec3 pn_swl_unbounded_on(const pn_swl *w, vec3 rgb);
vec3 pn_swl_illuminant_on(const pn_swl *w, vec3 rgb);
vec3 pn_swl_rgb_on(const pn_swl *w, vec3 v);
vec3 pn_swl_xyz_on(const pn_swl *w, vec3 v);

/* A memo of unbounded spectra (rgb / (2 max), the key of pn_swl_unbounded_on) for a set of
 * receivers, each with its own wavelengths: one row per colour converted, one slot per receiver
 * in the row (a row is made when its colour is first converted). The VPL integrators convert the
 * intensities of a few hundred colours at each receiver's wavelengths, and illumcut's pair order
 * (a light cluster with every point of a point cluster, then the next pair) changes the
 * wavelengths from one conversion to the next, so the per-thread table of transport.c, which
 * keeps one set of wavelengths per colour, misses there; with the memo a colour's spectrum is
 * evaluated once per receiver, and the receivers of one pair read one row in order. The values
 * are the ones the conversion computes without a memo, bit for bit. A memo is used by one thread
 * at a time. */
typedef struct pn_swl_memo pn_swl_memo;

/* A memo for `receivers` receivers (at most `max_bytes` of rows; a colour beyond that is converted
 * without it); NULL when out of memory. */
pn_swl_memo *pn_swl_memo_new(int32_t receivers, size_t max_bytes);
void pn_swl_memo_free(pn_swl_memo *m);
/* Makes w, receiver `index` of memo, use it; w's wavelengths must not change while it is attached
 * (pn_swl_sample detaches). Copies of w share the slot, as they share the wavelengths. */
static inline void pn_swl_memo_attach(pn_swl *w, pn_swl_memo *memo, int32_t index) {
    w->memo = memo;
    w->memo_index = index;
}
static inline void pn_swl_memo_detach(pn_swl *w) {
    w->memo = NULL;
}

/* A reflectance at the wavelengths (rgb itself in RGB mode). */
static inline vec3 pn_swl_albedo(const pn_swl *w, vec3 rgb) {
    return pn_swl_active(w) ? pn_swl_albedo_on(w, rgb) : rgb;
}
/* An unbounded value at the wavelengths (rgb itself in RGB mode). */
static inline vec3 pn_swl_unbounded(const pn_swl *w, vec3 rgb) {
    return pn_swl_active(w) ? pn_swl_unbounded_on(w, rgb) : rgb;
}
/* An emission at the wavelengths (rgb itself in RGB mode). Linear in positive scale factors:
 * illuminant(k rgb) = k illuminant(rgb), so a light sample's radiance (the light's RGB times a
 * geometric factor) may be converted after the factor is applied. */
static inline vec3 pn_swl_illuminant(const pn_swl *w, vec3 rgb) {
    return pn_swl_active(w) ? pn_swl_illuminant_on(w, rgb) : rgb;
}
/* A radiance at the wavelengths as linear sRGB (v itself in RGB mode). */
static inline vec3 pn_swl_rgb(const pn_swl *w, vec3 v) {
    return pn_swl_active(w) ? pn_swl_rgb_on(w, v) : v;
}
/* The luminance (CIE Y) of a value at the wavelengths (v3_luminance in RGB mode). */
static inline float pn_swl_luminance(const pn_swl *w, vec3 v) {
    return pn_swl_active(w) ? pn_swl_xyz_on(w, v).y : v3_luminance(v);
}

/* A black body's emission at `kelvin` at the wavelengths, scaled so that its luminance equals that
 * of rgb (the value RGB mode uses for it): Y(rgb) * planck(lambda) * unit_scale, with unit_scale
 * from pn_blackbody_unit_scale. RGB mode: rgb. */
vec3 pn_swl_blackbody(const pn_swl *w, float kelvin, float unit_scale, vec3 rgb);
/* 1 / the luminance of Planck's law at `kelvin` (W / (m^2 sr m) as pn_planck): the factor that
 * gives the black body luminance 1. 0 for kelvin <= 0. */
double pn_blackbody_unit_scale(double kelvin);

/* A tabulated emission spectrum kept as a spectrum in spectral mode (a "spectrum" value given as
 * numbers, an .spd file, or a named illuminant, whose CIE tables cie.h has):
 * piecewise linear between its wavelengths and held at its end values outside them, as
 * scene/spectrum.c reads the same values for RGB mode. scale is 1 / the function's luminance
 * (∫ ȳ S dλ / ∫ ȳ dλ with cie.h's tables, trapezoid rule at 0.1 nm; 0 without luminance). */
typedef struct pn_spd {
    int count;
    double *lambda, *value; /* count each, lambda increasing */
    double scale;
} pn_spd;

/* A new pn_spd of `count` (lambda, value) pairs (increasing lambda); NULL when out of memory. A
 * function without luminance gets scale 0 (it emits nothing, as its RGB). Free with pn_spd_free. */
pn_spd *pn_spd_new(const double *pairs, int count);
void pn_spd_free(pn_spd *s);
/* The function at lambda (nm). */
double pn_spd_eval(const pn_spd *s, double lambda);
/* The piecewise linear function of n knots (lambda_nm increasing, value) at lambda, end values
 * held outside (pn_spd_eval's rule). */
double pn_table_eval(const double *lambda_nm, const double *value, int n, double lambda);
/* A tabulated emission at the wavelengths, scaled so that its luminance equals that of rgb (the
 * value RGB mode uses for it, as pn_swl_blackbody): Y(rgb) * scale * S(lambda). RGB mode: rgb. */
vec3 pn_swl_tabulated(const pn_swl *w, const pn_spd *s, vec3 rgb);

/* The colour space's illuminant, normalised to luminance 1 (pbrt-v4's normalisation of
 * stdillum-D65), at lambda (nm). */
double pn_swl_d65(double lambda);

#endif
