/* sky.h — daylight skies generated at load time as environment images (scene/sky.c), so that
 * every integrator renders them through the existing environment light. */
#ifndef PN_SCENE_SKY_H
#define PN_SCENE_SKY_H

#include "scene/params.h"
#include "scene/scene.h"

/* The sky models ("string sky" of an infinite light). */
typedef enum pn_sky_model {
    PN_SKY_NONE = 0,
    PN_SKY_CIE_OVERCAST = 1, /* CIE standard overcast sky (CIE S 011/E:2003 type 1; Moon & Spencer 1942) */
    PN_SKY_CIE_CLEAR = 2     /* CIE standard general sky type 12: clear, low turbidity (CIE S 011/E:2003) */
} pn_sky_model;

/* The equal-area octahedral images are this many texels square. */
#define PN_SKY_RESOLUTION 512

/* Appends to scene->images the sky `name` (from ps's "sky" parameter, whose location errors
 * name) as an equal-area octahedral RGB image in the light's frame, +z the zenith, in scene
 * radiance units (luminance in cd/m^2, docs/units.md), scaled so that its horizontal
 * illuminance, integrated over the image's texels as the environment light reads them (nearest
 * texel), is `illuminance_lux` exactly. Below the horizon the image is black. *image receives
 * its index. An unknown name or an illuminance that is not positive: PN_ERROR_BAD_INPUT at the
 * parameter. */
pn_status pn_sky_image(struct pn_scene_s *scene, const pn_params *ps, const char *name, double illuminance_lux,
                       int *image, pn_err *err);

/* The CIE overcast sky's relative luminance at elevation h above the horizon (sin_h = sin h):
 * L(h) / L_z = (1 + 2 sin h) / 3, zero below the horizon; and its zenith luminance for a
 * horizontal illuminance E: L_z = 9 E / (7 pi) (the integral of L cos over the hemisphere is
 * L_z 2 pi (1/2 + 2/3) / 3 = 7 pi L_z / 9). */
double pn_sky_overcast_relative(double sin_h);
double pn_sky_overcast_zenith(double illuminance_lux);

/* The CIE standard general sky (CIE S 011/E:2003) of type 12, the CIE standard clear sky with
 * low luminance turbidity: relative luminance L / L_z = f(chi) phi(Z) / (f(Z_s) phi(0)) of the
 * sky element at zenith angle Z (cos_z = cos Z > 0; 0 below the horizon) and angular distance
 * chi from the sun (cos_chi), for the sun at zenith angle Z_s (cos_zs), with the gradation
 * phi(Z) = 1 + a exp(b / cos Z) and the indicatrix f(chi) = 1 + c (exp(d chi) - exp(d pi / 2)) +
 * e cos^2 chi, a = -1, b = -0.32, c = 10, d = -3, e = 0.45. */
double pn_sky_clear_relative(double cos_z, double cos_chi, double cos_zs);

/* The sun's apparent position (NOAA's solar calculator: Meeus's low-accuracy solar coordinates,
 * the equation of time, and NOAA's refraction correction) at local standard time `hours` (0-24)
 * of the Gregorian date, `timezone` hours east of UTC, at latitude and longitude in degrees
 * (north and east positive). Zenith angle and azimuth (clockwise from north) in degrees; the
 * declination (degrees) and the equation of time (minutes) as computed on the way. */
typedef struct pn_sun_position {
    double zenith_deg, azimuth_deg;
    double declination_deg, equation_of_time_min;
} pn_sun_position;
pn_sun_position pn_sun_position_at(int year, int month, int day, double hours, double timezone, double latitude,
                                   double longitude);

/* The sun of a "cie-clear" sky (ps's "string date", "float time", "float timezone", "float
 * latitude", "float longitude", "float sunilluminance"): its direction in the light's frame
 * (+z the zenith, +y north, +x east) and its illuminance on a plane normal to it (lx: the
 * direct horizontal illuminance "sunilluminance" over the cosine of its zenith angle; 0 when
 * "sunilluminance" is 0). Missing or out-of-range values, or the sun below the horizon:
 * PN_ERROR_BAD_INPUT at the parameter. */
pn_status pn_sky_sun(const pn_params *ps, vec3 *direction, double *normal_lux, pn_err *err);

/* Whether the infinite light of ps asks for a sky ("string sky"); its name in *name. */
pn_status pn_sky_requested(const pn_params *ps, const char **name, pn_err *err);

#endif
