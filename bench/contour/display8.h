/* display8.h — the 8-bit display value of a linear radiance channel (sRGB transfer curve, clamped
 * to [0, 1]): the unit of Vedel 1993's Table 1 "average difference", shared by the bench tools. */
#ifndef PN_BENCH_DISPLAY8_H
#define PN_BENCH_DISPLAY8_H

#include <math.h>

static inline int to_8bit(float linear) {
    double v = linear <= 0.0f ? 0.0 : (double)linear;
    double s = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
    if (s > 1.0) s = 1.0;
    return (int)lround(s * 255.0);
}

#endif
