/* sky.h — daylight skies generated at load time as environment images (scene/sky.c), so that
 * every integrator renders them through the existing environment light. */
#ifndef PN_SCENE_SKY_H
#define PN_SCENE_SKY_H

#include "scene/params.h"
#include "scene/scene.h"

/* The sky models ("string sky" of an infinite light). */
typedef enum pn_sky_model {
    PN_SKY_NONE = 0,
    PN_SKY_CIE_OVERCAST = 1 /* CIE standard overcast sky (CIE S 011/E:2003 type 1; Moon & Spencer 1942) */
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

/* Whether the infinite light of ps asks for a sky ("string sky"); its name in *name. */
pn_status pn_sky_requested(const pn_params *ps, const char **name, pn_err *err);

#endif
