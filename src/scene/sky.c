/* sky.c — the CIE standard overcast sky, and the CIE standard clear sky (general sky type 12)
 * with the sun's position from date, time and site, as environment images generated at load time
 * (see sky.h). The luminance distribution is the CIE's (Moon & Spencer 1942; CIE S 011/E:2003 type 1):
 * L(h) = L_z (1 + 2 sin h) / 3, independent of azimuth, with L_z fixed by the horizontal
 * illuminance asked for. The image uses pbrt-v4's equal-area octahedral mapping, so every texel
 * covers 4 pi / N sr; only a texel's elevation matters, and z of the mapping's point (u, v) is
 * sign(1 - |x| - |y|) (1 - r^2) with x = 2u - 1, y = 2v - 1, r = 1 - |1 - |x| - |y||.
 *
 * Discretisation: each texel holds the mean luminance of 4 x 4 points inside it, and the whole
 * image is scaled so that sum_i L_i (integral of cos over texel i) equals the horizontal
 * illuminance, the integral estimated from the same 4 x 4 points. The renderers read the map by
 * nearest texel, so this is the illuminance they integrate; the scale differs from the analytic
 * L_z by 2e-6 at 512 x 512 (the horizon texels).
 *
 * The clear sky (CIE S 011/E:2003, type 12; sky.h gives the formula) depends on the angle chi
 * between the sky element and the sun, so a texel's 4 x 4 points take their whole direction
 * from pbrt-v4's equal-area mapping, in the light's frame with +z the zenith, +y north and +x
 * east. Its image holds the diffuse sky only, scaled in the same way to the horizontal diffuse
 * illuminance asked for ("float illuminance"); the sun is a distant light of its own
 * (lightdefs.c), with the direct horizontal illuminance "sunilluminance". Its position is NOAA's
 * solar calculator (after Meeus, Astronomical Algorithms, ch. 25 and 28): about 0.01 degree from
 * NREL's SPA for dates between 1800 and 2100, far below what a sky model resolves. */
#include "scene/sky.h"

#include "core/photometry.h"
#include "core/vecmath.h"
#include "scene/parser_internal.h"
#include "scene/tokenizer.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SKY_SUBSAMPLES 4
#define PN_PI_D 3.14159265358979323846

double pn_sky_overcast_relative(double sin_h) {
    return sin_h > 0.0 ? (1.0 + 2.0 * sin_h) / 3.0 : 0.0;
}

double pn_sky_overcast_zenith(double illuminance_lux) {
    return 9.0 * illuminance_lux / (7.0 * PN_PI_D);
}

/* z (the sine of the elevation) of the equal-area octahedral mapping at (u, v) in [0, 1]^2. */
static double equal_area_z(double u, double v) {
    double x = 2.0 * u - 1.0, y = 2.0 * v - 1.0;
    double signed_distance = 1.0 - (fabs(x) + fabs(y));
    double r = 1.0 - fabs(signed_distance);
    return copysign(1.0 - r * r, signed_distance);
}

pn_status pn_sky_requested(const pn_params *ps, const char **name, pn_err *err) {
    return pn_params_string(ps, "sky", "", name, err);
}

static pn_sky_model sky_model(const char *name) {
    if (strcmp(name, "cie-overcast") == 0) return PN_SKY_CIE_OVERCAST;
    if (strcmp(name, "cie-clear") == 0) return PN_SKY_CIE_CLEAR;
    return PN_SKY_NONE;
}

/* ---- the CIE standard clear sky (general sky type 12) ----------------------------------------- */

#define CIE12_A (-1.0)
#define CIE12_B (-0.32)
#define CIE12_C 10.0
#define CIE12_D (-3.0)
#define CIE12_E 0.45

/* Gradation: the luminance's variation with the zenith angle (1 at the horizon). */
static double cie_gradation(double cos_z) {
    return cos_z > 0.0 ? 1.0 + CIE12_A * exp(CIE12_B / cos_z) : 1.0;
}

/* Scattering indicatrix: its variation with the angular distance chi from the sun. */
static double cie_indicatrix(double cos_chi) {
    double chi = acos(fmax(-1.0, fmin(1.0, cos_chi)));
    return 1.0 + CIE12_C * (exp(CIE12_D * chi) - exp(CIE12_D * PN_PI_D / 2.0)) + CIE12_E * cos_chi * cos_chi;
}

double pn_sky_clear_relative(double cos_z, double cos_chi, double cos_zs) {
    if (!(cos_z > 0.0)) return 0.0;
    return cie_indicatrix(cos_chi) * cie_gradation(cos_z) / (cie_indicatrix(cos_zs) * cie_gradation(1.0));
}

/* ---- the sun's position (NOAA's solar calculator) ------------------------------------------------ */

static double rad(double deg) {
    return deg * (PN_PI_D / 180.0);
}
static double deg(double r) {
    return r * (180.0 / PN_PI_D);
}

/* Julian day of 0h UT of a Gregorian calendar date (Meeus, ch. 7). */
static double julian_day(int year, int month, int day) {
    if (month <= 2) {
        year -= 1;
        month += 12;
    }
    double a = floor(year / 100.0), b = 2.0 - a + floor(a / 4.0);
    return floor(365.25 * (year + 4716)) + floor(30.6001 * (month + 1)) + day + b - 1524.5;
}

/* NOAA's correction of the elevation h (degrees) for atmospheric refraction, in degrees. */
static double refraction_deg(double h) {
    if (h > 85.0) return 0.0;
    double t = tan(rad(h));
    if (h > 5.0) return (58.1 / t - 0.07 / (t * t * t) + 0.000086 / pow(t, 5.0)) / 3600.0;
    if (h > -0.575) return (1735.0 + h * (-518.2 + h * (103.4 + h * (-12.79 + h * 0.711)))) / 3600.0;
    return -20.772 / t / 3600.0;
}

pn_sun_position pn_sun_position_at(int year, int month, int day, double hours, double timezone, double latitude,
                                   double longitude) {
    pn_sun_position out;
    /* Julian centuries since J2000.0 of the instant (UT). */
    const double jd = julian_day(year, month, day) + (hours - timezone) / 24.0;
    const double t = (jd - 2451545.0) / 36525.0;
    /* The sun's geometric mean longitude and anomaly, the orbit's eccentricity. */
    const double l0 = fmod(280.46646 + t * (36000.76983 + t * 0.0003032), 360.0);
    const double m = 357.52911 + t * (35999.05029 - 0.0001537 * t);
    const double ecc = 0.016708634 - t * (0.000042037 + 0.0000001267 * t);
    /* Equation of the centre, true and apparent longitude (nutation and aberration). */
    const double centre = sin(rad(m)) * (1.914602 - t * (0.004817 + 0.000014 * t)) +
                          sin(rad(2.0 * m)) * (0.019993 - 0.000101 * t) + sin(rad(3.0 * m)) * 0.000289;
    const double omega = 125.04 - 1934.136 * t;
    const double lambda = l0 + centre - 0.00569 - 0.00478 * sin(rad(omega));
    /* Obliquity of the ecliptic, corrected; the declination. */
    const double eps0 = 23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0;
    const double eps = eps0 + 0.00256 * cos(rad(omega));
    const double decl = asin(sin(rad(eps)) * sin(rad(lambda)));
    /* Equation of time (minutes). */
    const double y = tan(rad(eps / 2.0)) * tan(rad(eps / 2.0));
    const double eot =
        4.0 * deg(y * sin(2.0 * rad(l0)) - 2.0 * ecc * sin(rad(m)) + 4.0 * ecc * y * sin(rad(m)) * cos(2.0 * rad(l0)) -
                  0.5 * y * y * sin(4.0 * rad(l0)) - 1.25 * ecc * ecc * sin(2.0 * rad(m)));
    /* True solar time (minutes) and the hour angle (degrees, 0 at solar noon). */
    double tst = fmod(hours * 60.0 + eot + 4.0 * longitude - 60.0 * timezone, 1440.0);
    if (tst < 0.0) tst += 1440.0;
    const double hour_angle = tst / 4.0 - 180.0;
    const double phi = rad(latitude);
    double cos_z = sin(phi) * sin(decl) + cos(phi) * cos(decl) * cos(rad(hour_angle));
    cos_z = fmax(-1.0, fmin(1.0, cos_z));
    const double zenith = deg(acos(cos_z));
    /* Azimuth clockwise from north. */
    double azimuth;
    const double denom = cos(phi) * sin(rad(zenith));
    if (fabs(denom) > 1e-12) {
        double c = (sin(phi) * cos_z - sin(decl)) / denom;
        double a = deg(acos(fmax(-1.0, fmin(1.0, c))));
        azimuth = hour_angle > 0.0 ? fmod(a + 180.0, 360.0) : fmod(540.0 - a, 360.0);
    } else {
        azimuth = latitude > 0.0 ? 180.0 : 0.0; /* at a pole, or the sun at the zenith */
    }
    out.zenith_deg = zenith - refraction_deg(90.0 - zenith);
    out.azimuth_deg = azimuth;
    out.declination_deg = deg(decl);
    out.equation_of_time_min = eot;
    return out;
}

/* A float parameter that must be given and lie in [lo, hi]. */
static pn_status required_float(const pn_params *ps, const char *name, double lo, double hi, double *out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    pn_status st = pn_params_float(ps, name, NAN, out, err);
    if (st != PN_OK) return st;
    if (!(*out >= lo && *out <= hi))
        return pn_loc_error(p ? &p->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "sky \"cie-clear\" needs \"float %s\" in [%g, %g]", name, lo, hi);
    return PN_OK;
}

pn_status pn_sky_sun(const pn_params *ps, vec3 *direction, double *normal_lux, pn_err *err) {
    const char *date = "";
    pn_status st = pn_params_string(ps, "date", "", &date, err);
    if (st != PN_OK) return st;
    const pn_param *at = pn_params_find(ps, "date");
    int year = 0, month = 0, day = 0;
    char tail = 0;
    if (sscanf(date, "%d-%d-%d%c", &year, &month, &day, &tail) != 3 || year < 1 || month < 1 || month > 12 || day < 1 ||
        day > 31)
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "sky \"cie-clear\" needs \"string date\" as YYYY-MM-DD (got \"%s\")", date);
    double hours, timezone = 0.0, latitude, longitude, sun_lux = 0.0;
    st = required_float(ps, "time", 0.0, 24.0, &hours, err);
    if (st == PN_OK && pn_params_find(ps, "timezone")) st = required_float(ps, "timezone", -14.0, 14.0, &timezone, err);
    if (st == PN_OK) st = required_float(ps, "latitude", -90.0, 90.0, &latitude, err);
    if (st == PN_OK) st = required_float(ps, "longitude", -180.0, 180.0, &longitude, err);
    if (st == PN_OK && pn_params_find(ps, "sunilluminance"))
        st = required_float(ps, "sunilluminance", 0.0, 1e6, &sun_lux, err);
    if (st != PN_OK) return st;
    pn_sun_position sun = pn_sun_position_at(year, month, day, hours, timezone, latitude, longitude);
    const double cos_zs = cos(rad(sun.zenith_deg));
    if (!(cos_zs > 1e-3))
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "sky \"cie-clear\": the sun is below the horizon (zenith angle %.2f degrees) on %s at "
                            "%g h; the CIE clear sky needs it above",
                            sun.zenith_deg, date, hours);
    const double sin_zs = sin(rad(sun.zenith_deg)), az = rad(sun.azimuth_deg);
    *direction = v3((float)(sin_zs * sin(az)), (float)(sin_zs * cos(az)), (float)cos_zs);
    *normal_lux = sun_lux / cos_zs;
    return PN_OK;
}

/* pbrt-v4's equal-area octahedral mapping of (u, v) in [0, 1]^2 to the unit sphere (Clarberg
 * 2008), in double precision; z as equal_area_z computes it. */
static void equal_area_direction(double u, double v, double *dx, double *dy, double *dz) {
    double x = 2.0 * u - 1.0, y = 2.0 * v - 1.0, ax = fabs(x), ay = fabs(y);
    double signed_distance = 1.0 - (ax + ay);
    double r = 1.0 - fabs(signed_distance);
    double phi = (r == 0.0 ? 1.0 : (ay - ax) / r + 1.0) * (PN_PI_D / 4.0);
    double s = r * sqrt(fmax(0.0, 2.0 - r * r));
    *dx = copysign(cos(phi), x) * s;
    *dy = copysign(sin(phi), y) * s;
    *dz = copysign(1.0 - r * r, signed_distance);
}

pn_status pn_sky_image(struct pn_scene_s *scene, const pn_params *ps, const char *name, double illuminance_lux,
                       int *image, pn_err *err) {
    *image = -1;
    const pn_param *at = pn_params_find(ps, "sky");
    const pn_sky_model model = sky_model(name);
    if (model == PN_SKY_NONE)
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "unknown sky \"%s\" (penumbra has \"cie-overcast\" and \"cie-clear\")", name);
    if (!(illuminance_lux > 0.0) || !isfinite(illuminance_lux))
        return pn_loc_error(at ? &at->loc : &ps->loc, PN_ERROR_BAD_INPUT, err,
                            "sky \"%s\" needs a positive \"float illuminance\" (lux on an unobstructed horizontal "
                            "plane)",
                            name);
    /* The clear sky's sun, in the light's frame. */
    vec3 sun = v3(0, 0, 1);
    double sun_normal_lux = 0.0;
    if (model == PN_SKY_CIE_CLEAR) {
        pn_status st = pn_sky_sun(ps, &sun, &sun_normal_lux, err);
        if (st != PN_OK) return st;
    }
    const int n = PN_SKY_RESOLUTION;
    float *rgb = malloc(3 * (size_t)n * (size_t)n * sizeof *rgb);
    char *path = malloc(96);
    if (!rgb || !path || !pn_grow_for_append((void **)&scene->images, scene->image_count, sizeof *scene->images)) {
        free(rgb);
        free(path);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the sky image");
    }
    /* Relative luminance per texel and the horizontal illuminance it gives. */
    const double texel_sr = 4.0 * PN_PI_D / ((double)n * (double)n);
    const double sub = 1.0 / (double)SKY_SUBSAMPLES;
    double e_relative = 0.0;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            double l_sum = 0.0, cos_sum = 0.0;
            for (int j = 0; j < SKY_SUBSAMPLES; j++)
                for (int i = 0; i < SKY_SUBSAMPLES; i++) {
                    double pu = ((double)x + ((double)i + 0.5) * sub) / (double)n,
                           pv = ((double)y + ((double)j + 0.5) * sub) / (double)n;
                    double z;
                    if (model == PN_SKY_CIE_OVERCAST) {
                        z = equal_area_z(pu, pv);
                        l_sum += pn_sky_overcast_relative(z);
                    } else {
                        double dx, dy;
                        equal_area_direction(pu, pv, &dx, &dy, &z);
                        double cos_chi = dx * (double)sun.x + dy * (double)sun.y + z * (double)sun.z;
                        l_sum += pn_sky_clear_relative(z, cos_chi, (double)sun.z);
                    }
                    cos_sum += z > 0.0 ? z : 0.0;
                }
            double l = l_sum * sub * sub;
            e_relative += l * cos_sum * sub * sub * texel_sr;
            float *px = rgb + 3 * ((size_t)y * (size_t)n + (size_t)x);
            px[0] = px[1] = px[2] = (float)l;
        }
    /* cd/m^2 per unit relative luminance: scene radiance is luminance (docs/units.md). */
    const double scale = illuminance_lux / e_relative;
    for (size_t k = 0; k < 3 * (size_t)n * (size_t)n; k++) rgb[k] = (float)((double)rgb[k] * scale);
    snprintf(path, 96, "<sky %s, %.6g lx>", name, illuminance_lux);
    pn_texture_image *ti = &scene->images[scene->image_count];
    ti->width = n;
    ti->height = n;
    ti->rgb = rgb;
    ti->path = path;
    *image = scene->image_count++;
    return PN_OK;
}
