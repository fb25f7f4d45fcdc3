/* photometry.h — the one conversion between penumbra's radiometric scene values and SI
 * photometry (docs/lighting-design.md, "Units"). Scene values are pbrt-v4's radiometric ones in
 * the film's linear RGB (Rec. 709 / sRGB primaries, D65 white); the photometric quantity of an
 * RGB value is 683 lm/W times its CIE Y (v3_luminance): radiance W/(m^2 sr) -> luminance cd/m^2,
 * irradiance W/m^2 -> illuminance lux, intensity W/sr -> candela. A luminaire given in candela is
 * therefore an intensity of (candela / 683) in scene units of luminance 1 per RGB white. */
#ifndef PN_CORE_PHOTOMETRY_H
#define PN_CORE_PHOTOMETRY_H

#include "core/vecmath.h"

/* The luminous efficacy that defines the candela: 683 lm/W at 540 THz (555 nm). */
#define PN_LUMENS_PER_WATT 683.0f

/* The photometric value of a radiometric linear-RGB value (lux of W/m^2, cd/m^2 of W/(m^2 sr)). */
static inline float pn_photometric(vec3 rgb) {
    return PN_LUMENS_PER_WATT * v3_luminance(rgb);
}

#endif
