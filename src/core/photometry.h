/* photometry.h — the one conversion between penumbra's scene values and SI photometry
 * (docs/units.md). pbrt-v4 divides every light's spectrum by its photometric value before
 * applying scale and power, so scene values are photometric numbers with the colour separated
 * out: the photometric quantity of a linear-RGB value (Rec. 709 / sRGB primaries, D65 white) is
 * its CIE Y (v3_luminance) itself: luminance cd/m^2 of a radiance, illuminance lux of an
 * irradiance, candela of an intensity. A luminaire of 1000 cd is "rgb I" [1000 1000 1000]. */
#ifndef PN_CORE_PHOTOMETRY_H
#define PN_CORE_PHOTOMETRY_H

#include "core/vecmath.h"

/* The photometric value of a linear-RGB value (lux of an irradiance, cd/m^2 of a radiance). */
static inline float pn_photometric(vec3 rgb) {
    return v3_luminance(rgb);
}

#endif
