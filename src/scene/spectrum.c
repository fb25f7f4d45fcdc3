/* spectrum.c — turning pbrt-v4 colour parameters (rgb, blackbody, spectrum) into linear sRGB.
 *
 * penumbra renders in RGB, so every spectral quantity of a pbrt-v4 scene is reduced to three
 * numbers when the scene is read:
 *
 *  - "rgb" values are taken as linear Rec.709/sRGB. Reflectances (PN_SPECTRUM_ALBEDO) are clamped
 *    to [0, 1]; the material builder warns about it (pn_params_texref), this file clamps silently
 *    because it has no scene to warn on.
 *  - "blackbody" T: the Planck spectrum at T kelvin is integrated against the CIE 1931 colour
 *    matching functions, XYZ is converted to linear sRGB and the result is scaled to luminance 1
 *    (pbrt-v4 divides every light spectrum by its photometric value, so only the colour of a
 *    blackbody matters; its brightness comes from "scale" / "power"). A second value, as in
 *    pbrt-v3 files, multiplies the result.
 *  - "spectrum" [lambda value ...]: a piecewise linear function, held constant beyond its first
 *    and last wavelength. Reflectances and unbounded quantities (eta, k) use an equal-energy
 *    normalised conversion: the RGB of the spectrum divided channel by channel by the RGB of the
 *    constant spectrum 1, so a constant spectrum c becomes (c, c, c). Illuminants are converted
 *    like pbrt-v4 does: XYZ -> sRGB without white balancing, normalised to luminance 1.
 *  - "spectrum" "name": the named spectra of pbrt-v4. Metals (metal-X-eta / metal-X-k) are
 *    reduced to the values of pbrt-v4's tabulated data at 630 nm (red), 532 nm (green) and 465 nm
 *    (blue), interpolated linearly between the tabulated wavelengths (CuZn, brass, is an
 *    approximation at the same wavelengths). Glasses (glass-BK7, ...) are a single index at
 *    550 nm in all three channels. Standard illuminants (stdillum-A, -D50, -D65, -F1 ... -F12,
 *    illum-acesD60) keep their colour: the linear sRGB of their CIE chromaticity at luminance 1
 *    (so D65 is white and A orange, as pbrt-v4 renders them); other stdillum-/illum- names are
 *    an error, as in pbrt-v4.
 *  - "spectrum" "file.spd": whitespace-separated lambda/value pairs ('#' starts a comment),
 *    relative to the directive's folder, then as numeric pairs.
 * Spectra outside the sRGB gamut (very red or very blue emitters, saturated reflectances) would
 * get negative channels; those are set to 0.
 *
 * Spectral mode (--spectral, spectral/transport.h) upsamples these RGB values where they are used,
 * except for light emission that has a spectrum of its own: a "blackbody" value is also kept as
 * its temperature (pn_params_blackbody_kelvin, pn_light_def.kelvin, pn_emission.kelvin), and a
 * "spectrum" given as numbers, an .spd file or a named illuminant (stdillum-*, illum-acesD60: the CIE
 * tables of spectral/cie.h) as the tabulated function
 * (pn_params_light_spectrum: a pn_spd owned by the scene, pn_light_def.spd, pn_emission.spd), and
 * spectral mode emits those (Planck's law, the table) scaled to the luminance of the RGB value
 * read here. Negative tabulated values are dropped there as negative channels are here.
 *
 * The colour matching functions are the multi-lobe Gaussian fit of Wyman, Sloan and Shirley,
 * "Simple Analytic Approximations to the CIE XYZ Color Matching Functions", JCGT 2(2), 2013.
 */
#include "scene/build.h"

#include "core/file.h"
#include "spectral/cie.h"
#include "spectral/transport.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Integration range and step of the colour matching functions (nm). */
#define PN_LAMBDA_MIN 360.0
#define PN_LAMBDA_MAX 830.0
#define PN_LAMBDA_STEP 1.0

/* ---- CIE 1931 colour matching functions (Wyman et al. 2013, multi-lobe fit) ---------------- */

/* A Gaussian lobe with different widths left and right of its centre. */
static double lobe(double lambda, double mu, double sigma_left, double sigma_right) {
    double s = lambda < mu ? sigma_left : sigma_right;
    double t = (lambda - mu) / s;
    return exp(-0.5 * t * t);
}

static double cmf_x(double l) {
    return 1.056 * lobe(l, 599.8, 37.9, 31.0) + 0.362 * lobe(l, 442.0, 16.0, 26.7) - 0.065 * lobe(l, 501.1, 20.4, 26.2);
}

static double cmf_y(double l) {
    return 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
}

static double cmf_z(double l) {
    return 1.217 * lobe(l, 437.0, 11.8, 36.0) + 0.681 * lobe(l, 459.0, 26.0, 13.8);
}

/* CIE XYZ -> linear sRGB (Rec.709 primaries, D65 white). */
static void xyz_to_rgb(const double xyz[3], double rgb[3]) {
    rgb[0] = 3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2];
    rgb[1] = -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2];
    rgb[2] = 0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2];
}

/* A spectrum to integrate: either piecewise linear samples or a blackbody temperature. */
typedef struct spectrum_fn {
    const double *pairs; /* lambda, value, lambda, value, ... (increasing lambda) */
    int pair_count;
    double kelvin; /* > 0: Planck's law instead of pairs */
} spectrum_fn;

/* Planck's law: spectral radiance at lambda (nm) of a black body at temperature T (K), in
 * arbitrary but consistent units. */
static double planck(double lambda_nm, double kelvin) {
    const double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
    double l = lambda_nm * 1e-9;
    double e = exp((h * c) / (l * kb * kelvin));
    return (2.0 * h * c * c) / (l * l * l * l * l * (e - 1.0));
}

/* Linear interpolation in sorted pairs, holding the end values outside the range. */
static double pairs_eval(const double *pairs, int n, double lambda) {
    if (n <= 0) return 0.0;
    if (lambda <= pairs[0]) return pairs[1];
    if (lambda >= pairs[2 * (n - 1)]) return pairs[2 * (n - 1) + 1];
    int lo = 0, hi = n - 1; /* pairs[2*lo] <= lambda < pairs[2*hi] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (pairs[2 * mid] <= lambda)
            lo = mid;
        else
            hi = mid;
    }
    double l0 = pairs[2 * lo], l1 = pairs[2 * hi];
    double t = (lambda - l0) / (l1 - l0);
    return pairs[2 * lo + 1] * (1.0 - t) + pairs[2 * hi + 1] * t;
}

static double spectrum_eval(const spectrum_fn *s, double lambda) {
    if (s->kelvin > 0.0) return planck(lambda, s->kelvin);
    return pairs_eval(s->pairs, s->pair_count, lambda);
}

/* XYZ of a spectrum (s == NULL: the constant spectrum 1), unnormalised Riemann sums. */
static void spectrum_xyz(const spectrum_fn *s, double xyz[3]) {
    xyz[0] = xyz[1] = xyz[2] = 0.0;
    for (double l = PN_LAMBDA_MIN; l <= PN_LAMBDA_MAX; l += PN_LAMBDA_STEP) {
        double v = s ? spectrum_eval(s, l) : 1.0;
        xyz[0] += v * cmf_x(l);
        xyz[1] += v * cmf_y(l);
        xyz[2] += v * cmf_z(l);
    }
}

/* RGB of a reflectance-like spectrum, normalised so that the constant spectrum c gives c. */
static vec3 spectrum_to_rgb_normalised(const spectrum_fn *s) {
    double xyz[3], rgb[3], xyz1[3], rgb1[3];
    spectrum_xyz(s, xyz);
    spectrum_xyz(NULL, xyz1);
    xyz_to_rgb(xyz, rgb);
    xyz_to_rgb(xyz1, rgb1);
    return v3((float)(rgb[0] / rgb1[0]), (float)(rgb[1] / rgb1[1]), (float)(rgb[2] / rgb1[2]));
}

/* RGB of an emission spectrum with luminance 1 (black when the spectrum has no luminance). */
static vec3 spectrum_to_rgb_unit_luminance(const spectrum_fn *s) {
    double xyz[3], rgb[3];
    spectrum_xyz(s, xyz);
    if (!(xyz[1] > 0.0) || !isfinite(xyz[1])) return v3(0, 0, 0);
    double y = xyz[1];
    for (int i = 0; i < 3; i++) xyz[i] /= y;
    xyz_to_rgb(xyz, rgb);
    /* Very red or blue emitters fall outside the sRGB gamut; negative emission is dropped. */
    return v3((float)fmax(0.0, rgb[0]), (float)fmax(0.0, rgb[1]), (float)fmax(0.0, rgb[2]));
}

static vec3 clamp01(vec3 c) {
    return v3(fminf(1.0f, fmaxf(0.0f, c.x)), fminf(1.0f, fmaxf(0.0f, c.y)), fminf(1.0f, fmaxf(0.0f, c.z)));
}

/* ---- named spectra ------------------------------------------------------------------------- */

typedef struct named_spectrum {
    const char *name;
    float r, g, b; /* 630 nm, 532 nm, 465 nm (glasses: the index at 550 nm, three times) */
} named_spectrum;

/* Values of pbrt-v4's tabulated spectra, linearly interpolated at the wavelengths above. */
static const named_spectrum named_spectra[] = {
    {"metal-Ag-eta", 0.1342f, 0.1297f, 0.1395f},   {"metal-Ag-k", 3.9628f, 3.1942f, 2.6135f},
    {"metal-Al-eta", 1.3571f, 0.8843f, 0.6605f},   {"metal-Al-k", 7.5878f, 6.4700f, 5.6536f},
    {"metal-Au-eta", 0.1837f, 0.4573f, 1.3724f},   {"metal-Au-k", 3.0663f, 2.4084f, 1.8250f},
    {"metal-Cu-eta", 0.2459f, 1.0723f, 1.1569f},   {"metal-Cu-k", 3.3784f, 2.5907f, 2.4572f},
    {"metal-CuZn-eta", 0.445f, 0.568f, 0.947f},    {"metal-CuZn-k", 3.522f, 2.588f, 1.920f},
    {"metal-MgO-eta", 1.7347f, 1.7423f, 1.7502f},  {"metal-MgO-k", 0.0f, 0.0f, 0.0f},
    {"metal-TiO2-eta", 2.8748f, 2.9580f, 3.1143f}, {"metal-TiO2-k", 0.0f, 0.0f, 0.0f},
    {"glass-BK7", 1.5185f, 1.5185f, 1.5185f},      {"glass-BAF10", 1.6730f, 1.6730f, 1.6730f},
    {"glass-FK51A", 1.4878f, 1.4878f, 1.4878f},    {"glass-LASF9", 1.8558f, 1.8558f, 1.8558f},
    {"glass-F5", 1.6771f, 1.6771f, 1.6771f},       {"glass-F10", 1.7336f, 1.7336f, 1.7336f},
    {"glass-F11", 1.7911f, 1.7911f, 1.7911f},
};

/* pbrt-v4's named illuminants, by their CIE 1931 (2 degree) chromaticity (x, y) as tabulated by
 * the CIE (publication 15; ACES D60 from SMPTE ST 2065-1). pbrt-v4 normalises each to luminance
 * 1 and, with the default sensor, shows its colour without white balancing; penumbra does the
 * same with the exact chromaticity: XYZ = (x / y, 1, (1 - x - y) / y) in linear sRGB. D65 (listed
 * with x = y = 0) is exactly (1, 1, 1): pbrt-v4 derives its sRGB white point from the D65
 * spectrum itself, so stdillum-D65 is the colour space's white. F10's y is 0.35896, the value its
 * CIE table integrates to (0.3588 with the CIE's 5 nm sums, 0.3592 with interpolated tables; an
 * earlier 0.35986 here, 7e-4 off, apparently had two digits swapped). Spectral mode emits the
 * CIE tables themselves (pn_params_light_spectrum). */
typedef struct named_illuminant {
    const char *name;
    double x, y;
} named_illuminant;

static const named_illuminant named_illuminants[] = {
    {"stdillum-A", 0.44757, 0.40745},    {"stdillum-D50", 0.34567, 0.35850}, {"stdillum-D65", 0.0, 0.0},
    {"stdillum-F1", 0.31310, 0.33727},   {"stdillum-F2", 0.37208, 0.37529},  {"stdillum-F3", 0.40910, 0.39430},
    {"stdillum-F4", 0.44018, 0.40329},   {"stdillum-F5", 0.31379, 0.34531},  {"stdillum-F6", 0.37790, 0.38835},
    {"stdillum-F7", 0.31292, 0.32933},   {"stdillum-F8", 0.34588, 0.35875},  {"stdillum-F9", 0.37417, 0.37281},
    {"stdillum-F10", 0.34609, 0.35896},  {"stdillum-F11", 0.38052, 0.37713}, {"stdillum-F12", 0.43695, 0.40441},
    {"illum-acesD60", 0.32168, 0.33767},
};

static bool is_illuminant_name(const char *s) {
    return strncmp(s, "stdillum-", 9) == 0 || strncmp(s, "illum-", 6) == 0;
}

/* Linear sRGB of chromaticity (x, y) at luminance 1; out-of-gamut negatives set to 0. */
static vec3 chromaticity_rgb(double x, double y) {
    if (!(y > 0.0)) return v3(1, 1, 1); /* the white point */
    double xyz[3] = {x / y, 1.0, (1.0 - x - y) / y}, rgb[3];
    xyz_to_rgb(xyz, rgb);
    return v3((float)fmax(0.0, rgb[0]), (float)fmax(0.0, rgb[1]), (float)fmax(0.0, rgb[2]));
}

bool pn_named_spectrum_rgb(const char *name, vec3 *out) {
    for (size_t i = 0; i < sizeof named_spectra / sizeof named_spectra[0]; i++) {
        if (strcmp(named_spectra[i].name, name) == 0) {
            *out = v3(named_spectra[i].r, named_spectra[i].g, named_spectra[i].b);
            return true;
        }
    }
    for (size_t i = 0; i < sizeof named_illuminants / sizeof named_illuminants[0]; i++) {
        if (strcmp(named_illuminants[i].name, name) == 0) {
            *out = chromaticity_rgb(named_illuminants[i].x, named_illuminants[i].y);
            return true;
        }
    }
    return false;
}

/* ---- .spd files ---------------------------------------------------------------------------- */

/* Reads whitespace-separated numbers ('#' comments) into a malloc'ed array. On failure returns
 * false with a message in msg. */
static bool read_number_file(const char *path, double **out, int *count, char *msg, size_t msg_size) {
    *out = NULL;
    *count = 0;
    /* Only a regular file of at most 64 MiB (at most 2^25 numbers, so the count stays an int):
     * a FIFO must not block and a device must not stream without end. */
    uint64_t size = 0;
    pn_err why;
    pn_err_init(&why);
    FILE *f = pn_file_open_regular(path, (uint64_t)1 << 26, &size, &why);
    if (!f) {
        snprintf(msg, msg_size, "cannot open spectrum file \"%s\": %.200s", path, why.message);
        return false;
    }
    int cap = 0, n = 0;
    double *vals = NULL;
    char tok[128];
    int c = 0;
    bool ok = true;
    for (;;) {
        c = fgetc(f);
        if (c == EOF) break;
        if (c == '#') {
            while (c != EOF && c != '\n') c = fgetc(f);
            continue;
        }
        if (isspace(c) || c == ',') continue;
        size_t len = 0;
        while (c != EOF && !isspace(c) && c != '#' && c != ',') {
            if (len + 1 < sizeof tok) tok[len++] = (char)c;
            c = fgetc(f);
        }
        tok[len] = '\0';
        if (c == '#') ungetc(c, f);
        char *end = NULL;
        double v = strtod(tok, &end);
        if (end == tok || *end != '\0' || !isfinite(v)) {
            snprintf(msg, msg_size, "spectrum file \"%s\": \"%s\" is not a number", path, tok);
            ok = false;
            break;
        }
        if (n == cap) {
            int ncap = cap ? 2 * cap : 256;
            double *nv = realloc(vals, (size_t)ncap * sizeof *nv);
            if (!nv) {
                snprintf(msg, msg_size, "out of memory reading \"%s\"", path);
                ok = false;
                break;
            }
            vals = nv;
            cap = ncap;
        }
        vals[n++] = v;
        if (c == EOF) break;
    }
    fclose(f);
    if (!ok) {
        free(vals);
        return false;
    }
    *out = vals;
    *count = n;
    return true;
}

/* Checks numeric pairs: an even count of at least 2 values and increasing wavelengths. */
static bool check_pairs(const double *v, int n, char *msg, size_t msg_size) {
    if (n < 2 || n % 2 != 0) {
        snprintf(msg, msg_size, "a spectrum needs (wavelength, value) pairs, got %d value%s", n, n == 1 ? "" : "s");
        return false;
    }
    for (int i = 1; i < n / 2; i++) {
        if (!(v[2 * i] > v[2 * (i - 1)])) {
            snprintf(msg, msg_size, "spectrum wavelengths must increase (%g after %g)", v[2 * i], v[2 * (i - 1)]);
            return false;
        }
    }
    return true;
}

static vec3 pairs_to_rgb(const double *v, int n, pn_spectrum_use use) {
    spectrum_fn s = {v, n / 2, 0.0};
    if (use == PN_SPECTRUM_ILLUMINANT) return spectrum_to_rgb_unit_luminance(&s);
    vec3 c = v3_max(spectrum_to_rgb_normalised(&s), v3(0, 0, 0)); /* out-of-gamut negatives */
    return use == PN_SPECTRUM_ALBEDO ? clamp01(c) : c;
}

vec3 pn_blackbody_rgb(double kelvin) {
    if (!(kelvin > 0.0)) return v3(0, 0, 0);
    spectrum_fn s = {NULL, 0, kelvin};
    return spectrum_to_rgb_unit_luminance(&s);
}

vec3 pn_spectrum_pairs_rgb(const double *pairs, int value_count, pn_spectrum_use use) {
    if (value_count < 2) return v3(0, 0, 0);
    return pairs_to_rgb(pairs, value_count - value_count % 2, use);
}

/* ---- parameters ---------------------------------------------------------------------------- */

/* The numeric pairs of a string-form spectrum parameter that names an .spd file (loaded into
 * *vals, to be freed by the caller). */
static pn_status spd_file_pairs(const pn_params *ps, const pn_param *p, const char *file, double **vals, int *n,
                                pn_err *err) {
    char msg[512];
    char *path = pn_path_resolve(ps->base_dir, file);
    if (!path) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    bool ok = read_number_file(path, vals, n, msg, sizeof msg);
    free(path);
    if (!ok) return pn_param_error(p, err, "%s", msg);
    if (!check_pairs(*vals, *n, msg, sizeof msg)) {
        free(*vals);
        *vals = NULL;
        return pn_param_error(p, err, "\"%s\": %s", file, msg);
    }
    return PN_OK;
}

pn_status pn_params_rgb(const pn_params *ps, const char *name, vec3 def, pn_spectrum_use use, vec3 *out, bool *found,
                        pn_err *err) {
    *out = def;
    if (found) *found = false;
    const pn_param *p = pn_params_find(ps, name);
    if (!p) return PN_OK;
    char msg[256];
    vec3 c = def;
    switch (p->type) {
    case PN_PT_RGB:
        if (p->num_count != 3) return pn_param_error(p, err, "\"%s\" needs 3 values, got %d", name, p->num_count);
        c = v3((float)p->nums[0], (float)p->nums[1], (float)p->nums[2]);
        if (!v3_is_finite(c)) return pn_param_error(p, err, "\"%s\" has a value that is not finite", name);
        if (use == PN_SPECTRUM_ALBEDO) c = clamp01(c);
        break;
    case PN_PT_BLACKBODY: {
        if (p->num_count != 1 && p->num_count != 2)
            return pn_param_error(p, err, "blackbody \"%s\" needs a temperature in kelvin", name);
        double kelvin = p->nums[0];
        if (!(kelvin > 0.0) || !isfinite(kelvin))
            return pn_param_error(p, err, "blackbody temperature %g is not positive", kelvin);
        c = pn_blackbody_rgb(kelvin);
        if (p->num_count == 2) c = v3_scale(c, (float)p->nums[1]);
        if (use == PN_SPECTRUM_ALBEDO) c = clamp01(c);
        break;
    }
    case PN_PT_SPECTRUM:
        if (p->str_count > 0) {
            if (p->str_count != 1 || p->num_count != 0)
                return pn_param_error(p, err, "spectrum \"%s\" needs one name or file, or numbers", name);
            const char *s = p->strs[0];
            if (pn_named_spectrum_rgb(s, &c)) break;
            size_t len = strlen(s);
            bool looks_named = strncmp(s, "metal-", 6) == 0 || strncmp(s, "glass-", 6) == 0 || is_illuminant_name(s) ||
                               strncmp(s, "canon_", 6) == 0 || strncmp(s, "nikon_", 6) == 0 ||
                               strncmp(s, "sony_", 5) == 0;
            if (looks_named && !(len > 4 && strcmp(s + len - 4, ".spd") == 0))
                return pn_param_error(p, err, "unknown named spectrum \"%s\"", s);
            double *vals = NULL;
            int n = 0;
            pn_status st = spd_file_pairs(ps, p, s, &vals, &n, err);
            if (st != PN_OK) return st;
            c = pairs_to_rgb(vals, n, use);
            free(vals);
        } else {
            if (!check_pairs(p->nums, p->num_count, msg, sizeof msg))
                return pn_param_error(p, err, "\"%s\": %s", name, msg);
            for (int i = 0; i < p->num_count; i++)
                if (!isfinite(p->nums[i])) return pn_param_error(p, err, "\"%s\" has a value that is not finite", name);
            c = pairs_to_rgb(p->nums, p->num_count, use);
        }
        break;
    default: return pn_param_error(p, err, "\"%s\" must be an rgb, blackbody or spectrum value", name);
    }
    *out = c;
    if (found) *found = true;
    return PN_OK;
}

/* Appends a pn_spd of the pairs to the scene's table. */
static pn_status add_spd(struct pn_scene_s *scene, const double *pairs, int count, const pn_spd **out, pn_err *err) {
    pn_spd *s = pn_spd_new(pairs, count);
    pn_spd **grown = s ? realloc(scene->spds, (size_t)(scene->spd_count + 1) * sizeof *grown) : NULL;
    if (!grown) {
        pn_spd_free(s);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    scene->spds = grown;
    scene->spds[scene->spd_count++] = s;
    *out = s;
    return PN_OK;
}

/* A named illuminant's CIE table (5 nm steps) as pairs. A table that ends inside the range of the
 * matching functions (the CIE's 380-780 nm tables) is 0 beyond its ends, as pbrt-v4's piecewise
 * linear spectra are: a zero 1e-3 nm outside each end (pn_spd holds its end values). */
static pn_status add_cie_spd(struct pn_scene_s *scene, const pn_cie_illuminant *il, const pn_spd **out, pn_err *err) {
    double pairs[2 * (PN_CIE_TABLE_COUNT + 2)];
    int n = 0;
    const double last = il->lambda_min + 5.0 * (il->count - 1);
    if (il->lambda_min > PN_LAMBDA_MIN) {
        pairs[2 * n] = il->lambda_min - 1e-3;
        pairs[2 * n++ + 1] = 0.0;
    }
    for (int i = 0; i < il->count; i++) {
        pairs[2 * n] = il->lambda_min + 5.0 * i;
        pairs[2 * n++ + 1] = il->value[i];
    }
    if (last < PN_LAMBDA_MAX) {
        pairs[2 * n] = last + 1e-3;
        pairs[2 * n++ + 1] = 0.0;
    }
    return add_spd(scene, pairs, n, out, err);
}

pn_status pn_params_light_spectrum(struct pn_scene_s *scene, const pn_params *ps, const char *name, const pn_spd **out,
                                   pn_err *err) {
    *out = NULL;
    const pn_param *p = pn_params_find(ps, name);
    if (!p || p->type != PN_PT_SPECTRUM) return PN_OK;
    if (p->str_count == 0) {
        char msg[256];
        if (!check_pairs(p->nums, p->num_count, msg, sizeof msg))
            return pn_param_error(p, err, "\"%s\": %s", name, msg);
        /* Negative emission is dropped, as RGB mode drops negative channels. */
        double *v = malloc((size_t)p->num_count * sizeof *v);
        if (!v) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        for (int i = 0; i < p->num_count; i++) v[i] = i % 2 ? fmax(0.0, p->nums[i]) : p->nums[i];
        pn_status st = add_spd(scene, v, p->num_count / 2, out, err);
        free(v);
        return st;
    }
    if (p->str_count != 1) return PN_OK;
    const char *s = p->strs[0];
    const pn_cie_illuminant *il = pn_cie_illuminant_named(s);
    if (il) return add_cie_spd(scene, il, out, err);
    vec3 unused;
    if (pn_named_spectrum_rgb(s, &unused)) return PN_OK; /* other named spectra: their RGB, upsampled */
    double *vals = NULL;
    int n = 0;
    pn_status st = spd_file_pairs(ps, p, s, &vals, &n, err);
    if (st != PN_OK) return st;
    for (int i = 1; i < n; i += 2) vals[i] = fmax(0.0, vals[i]);
    st = add_spd(scene, vals, n / 2, out, err);
    free(vals);
    return st;
}

float pn_params_blackbody_kelvin(const pn_params *ps, const char *name) {
    const pn_param *p = pn_params_find(ps, name);
    if (!p || p->type != PN_PT_BLACKBODY || p->num_count < 1 || !(p->nums[0] > 0.0) || !isfinite(p->nums[0]))
        return 0.0f;
    return (float)p->nums[0];
}

pn_status pn_params_spectrum_value(const pn_params *ps, const char *name, double lambda_nm, double def, double *out,
                                   bool *found, pn_err *err) {
    *out = def;
    if (found) *found = false;
    const pn_param *p = pn_params_find(ps, name);
    if (!p) return PN_OK;
    char msg[256];
    double v = def;
    switch (p->type) {
    case PN_PT_FLOAT:
    case PN_PT_INTEGER:
        if (p->num_count != 1) return pn_param_error(p, err, "\"%s\" needs one value, got %d", name, p->num_count);
        v = p->nums[0];
        break;
    case PN_PT_RGB:
        if (p->num_count != 3) return pn_param_error(p, err, "\"%s\" needs 3 values, got %d", name, p->num_count);
        v = p->nums[1]; /* the green channel stands for the middle of the visible range */
        break;
    case PN_PT_SPECTRUM:
        if (p->str_count > 0) {
            if (p->str_count != 1) return pn_param_error(p, err, "spectrum \"%s\" needs one name or file", name);
            vec3 c;
            if (pn_named_spectrum_rgb(p->strs[0], &c)) {
                v = c.y;
                break;
            }
            double *vals = NULL;
            int n = 0;
            pn_status st = spd_file_pairs(ps, p, p->strs[0], &vals, &n, err);
            if (st != PN_OK) return st;
            v = pairs_eval(vals, n / 2, lambda_nm);
            free(vals);
        } else {
            if (!check_pairs(p->nums, p->num_count, msg, sizeof msg))
                return pn_param_error(p, err, "\"%s\": %s", name, msg);
            v = pairs_eval(p->nums, p->num_count / 2, lambda_nm);
        }
        break;
    default: return pn_param_error(p, err, "\"%s\" must be a float or a spectrum", name);
    }
    if (!isfinite(v)) return pn_param_error(p, err, "\"%s\" is not finite", name);
    *out = v;
    if (found) *found = true;
    return PN_OK;
}
